"""One rig builder: the servos, bus, faults and world a scenario describes.

``hexhil run`` (through the lockstep ``Simulator``), ``hexhil bus`` and the tests all build
their rig here, so a scenario means the same thing everywhere: the same servo IDs, control
table edition, return delay, baud register, EEPROM busy time and fault schedule.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

from hil import scenario as scenario_mod
from hil.servobus.line import Bus, OnBytes
from hil.servobus.bus2 import Bus2
from hil.clock import VirtualClock
from hil.servobus.faults import Faults, OnFault
from hil.servobus.ax12_servo import Servo
from hil.servobus.xl430_servo import XL430Servo
from protocol.dynamixel import ax12
from protocol.dynamixel import xl430
from protocol.errors import UserError


@dataclass
class Rig:
    """What a scenario builds; ``bus`` is None for a world with no servo bus (beams)."""

    config: scenario_mod.Scenario
    scenario: dict[str, Any]       # ``config.data``: what the worlds and the hello read
    seed: int
    clock: VirtualClock
    world: Any
    bus: Bus | None
    faults: Faults | None


def make_world(scenario: dict[str, Any] | scenario_mod.Scenario, seed: int) -> Any:
    """The hexapod world of a scenario's ``[world]``, or None (kinematic servos); the hexapod
    world refuses another kind. Seed 000's beams world is built with its host nodes
    (host_tools/traversal/closed_loop.py)."""
    cfg = scenario_mod.parse(scenario)
    if cfg.world.kind is None:
        return None
    from hil.world.hexapod import HexapodWorld
    return HexapodWorld(cfg.data, seed)


def _servos(bus: scenario_mod.BusConfig, ids: Sequence[int], world: Any) -> list[Servo]:
    actuators = world.actuators() if world is not None else []
    servos: list = []
    for k, dev_id in enumerate(ids):
        a = actuators[k] if k < len(actuators) else None
        if bus.model == xl430.MODEL_NAME:   # its bauds: checked by BusConfig
            if dev_id > 252:                 # IDs given apart from the scenario (hexhil bus --ids)
                raise UserError(f"servo ID {dev_id}: an {xl430.MODEL_NAME} takes IDs 0-252")
            x = XL430Servo(dev_id, actuator=a, eeprom_busy_us=bus.eeprom_busy_us, position=(
                xl430.rad_to_position(a.state()[0]) if a is not None else xl430.POSITION_CENTRE))
            x.table[xl430.RETURN_DELAY_TIME] = (500 if bus.return_delay_us is None
                                                else bus.return_delay_us) // 2
            x.table[xl430.BAUD_RATE] = xl430.bps_to_baud(bus.baud)
            servos.append(x)
            continue
        pos = ax12.rad_to_position(a.state()[0]) if a is not None else 512
        s = Servo(dev_id, bus.edition, actuator=a, position=pos,
                  eeprom_busy_us=bus.eeprom_busy_us)
        if bus.return_delay_us is not None:
            s.table[ax12.RETURN_DELAY_TIME] = bus.return_delay_us // 2
        # The register nearest the line's rate (checked within 3 % by the scenario rules).
        s.table[ax12.BAUD_RATE] = scenario_mod.baud_register(bus.baud)
        servos.append(s)
    return servos


def build(scenario: dict[str, Any] | scenario_mod.Scenario, seed: int = 0, *, world: Any = None,
          ids: Sequence[int] | None = None, on_fault: OnFault | None = None,
          on_bytes: OnBytes | None = None) -> Rig:
    """The rig of ``scenario`` (checked here, so a hand-built dict obeys the same rules)."""
    cfg = scenario_mod.parse(scenario)
    sc = cfg.data
    clock = VirtualClock()
    if world is not None and not hasattr(world, "actuators"):
        return Rig(cfg, sc, seed, clock, world, None, None)   # a world without a servo bus
    bus_cfg = cfg.bus
    faults = Faults.from_scenario(sc["faults"], seed, where=f"{cfg.path} [faults]",
                                  on_fault=on_fault)
    line = Bus2 if bus_cfg.model == xl430.MODEL_NAME else Bus
    bus = line(_servos(bus_cfg, list(bus_cfg.ids if ids is None else ids), world), clock,
              baud=bus_cfg.baud, echo=bus_cfg.echo, faults=faults if faults.active() else None,
              on_bytes=on_bytes, advance=world.advance_to if world is not None else None)
    return Rig(cfg, sc, seed, clock, world, bus, faults)
