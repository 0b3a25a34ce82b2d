"""Each Dynamixel protocol's parts on the servo bus, keyed by the version a model speaks
(protocol/dynamixel/models.py): the line that carries it, the emulated servo a model's
control table makes, and the rules the master check holds a master to.

A new model of an existing protocol needs nothing here: its table and its entry in
protocol/dynamixel/models.py; ``for_model`` finds its protocol's parts.
"""
from __future__ import annotations

from dataclasses import dataclass
from types import ModuleType
from typing import Callable

from hexhil.hil.scenario import BusConfig
from hexhil.hil.servobus.drive import Actuator
from hexhil.hil.servobus.line import Bus
from hexhil.hil.servobus.packet_check import KINDS, OnViolation, PacketCheck
from hexhil.hil.servobus.protocols import v1, v2
from hexhil.hil.servobus.table_servo import TableServo
from hexhil.protocol.dynamixel import models


@dataclass(frozen=True)
class ProtocolParts:
    """What the bus needs of one protocol."""

    version: int
    line: type[Bus]                   # byte timing, collisions, the packet layer
    make_servo: Callable[[ModuleType, int, Actuator | None, BusConfig], TableServo]
    check: Callable[[OnViolation], PacketCheck]   # the master check's rules
    kinds: tuple[str, ...]            # the violations those rules name


RULES = {
    1: ProtocolParts(1, Bus, v1.make_servo, v1.Packet1Check, KINDS),
    2: ProtocolParts(2, v2.Bus2, v2.make_servo, v2.Packet2Check,
                     KINDS + ("group_read_not_broadcast",)),
}


def for_model(name: str) -> ProtocolParts:
    """The parts of the protocol the servo model ``name`` speaks."""
    return RULES[models.protocol(name)]
