"""One rig builder: the servos, bus, faults and world a scenario describes.

``hexhil run`` (through the lockstep ``Simulator``), ``hexhil bus`` and the tests all build
their rig here, so a scenario means the same thing everywhere: the same servo IDs, control
table edition, return delay, baud register, EEPROM busy time and fault schedule.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

from hexhil.hil import scenario as scenario_mod
from hexhil.hil.seams import FirmwareWorld, SteppedWorld
from hexhil.hil.clock import VirtualClock
from hexhil.hil.servobus import protocols
from hexhil.hil.servobus.faults import Faults, OnFault
from hexhil.hil.servobus.line import Bus, OnBytes
from hexhil.hil.servobus.table_servo import TableServo
from hexhil.protocol.dynamixel import models


@dataclass
class Rig:
    """What a scenario builds; ``bus`` is None for a world with no servo bus (beams)."""

    config: scenario_mod.Scenario
    seed: int
    clock: VirtualClock
    world: FirmwareWorld | SteppedWorld | None
    bus: Bus | None
    faults: Faults | None


def make_world(scenario: dict[str, Any] | scenario_mod.Scenario, seed: int
               ) -> FirmwareWorld | None:
    """The hexapod world of a scenario's ``[world]``, or None (kinematic servos); the hexapod
    world refuses another kind. Seed 000's beams world is built with its host nodes
    (host_tools/papers/beam_traversal/beams_run.py)."""
    cfg = scenario_mod.parse(scenario)
    if cfg.world.kind is None:
        return None
    from hexhil.hil.world.hexapod_world import HexapodWorld
    return HexapodWorld(cfg, seed)


def _servos(bus: scenario_mod.BusConfig, ids: Sequence[int], world: FirmwareWorld | None
            ) -> list[TableServo]:
    """The scenario's model (protocol/dynamixel/models.py), one servo an ID, each on its
    joint's actuator when there is a world."""
    actuators = world.actuators() if world is not None else []
    layout = models.table(bus.model)
    make = protocols.for_model(bus.model).make_servo
    return [make(layout, dev_id, actuators[k] if k < len(actuators) else None, bus)
            for k, dev_id in enumerate(ids)]


def build(scenario: dict[str, Any] | scenario_mod.Scenario, seed: int = 0, *,
          world: FirmwareWorld | SteppedWorld | None = None,
          ids: Sequence[int] | None = None, on_fault: OnFault | None = None,
          on_bytes: OnBytes | None = None) -> Rig:
    """The rig of ``scenario`` (checked here, so a hand-built dict obeys the same rules)."""
    cfg = scenario_mod.parse(scenario)
    clock = VirtualClock()
    faults = Faults(cfg.faults, seed, on_fault=on_fault)
    if world is not None and not hasattr(world, "actuators"):
        return Rig(cfg, seed, clock, world, None, faults)   # a world without a servo bus
    bus_cfg = cfg.bus
    line = protocols.for_model(bus_cfg.model).line
    ids = list(bus_cfg.ids if ids is None else ids)
    cfg.faults.check_ids(cfg.path, ids)
    bus = line(_servos(bus_cfg, ids, world), clock,
              baud=bus_cfg.baud, echo=bus_cfg.echo, faults=faults if faults.active() else None,
              on_bytes=on_bytes, advance=world.advance_to if world is not None else None)
    return Rig(cfg, seed, clock, world, bus, faults)
