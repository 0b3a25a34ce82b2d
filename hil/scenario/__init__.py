"""Scenario files (TOML): one loader, one schema, typed sections, one-line errors.

Each section's keys and types are declared in ``SCHEMA``; each section's defaults and rules
sit beside its frozen type (sections.py; seed 000's in beams.py), applied once by ``parse``,
so ``hexhil run``, ``hexhil bus``, the experiments and the tests build the same rig from the
same file. ``float`` keys accept integers; ``list`` keys are checked further by their owner
(faults, terrain). ``load_scenario`` reads a file into a ``Scenario``; ``parse`` takes a
dict (tests build them); ``check``/``load`` give the checked dict its consumers still read.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hil.scenario.beams import BeamsConfig, TraversalConfig
from hil.scenario.sections import (DEFAULT_BAUD, DEFAULT_DURATION_S, GAITS,
                                   MAX_DURATION_S, RETURN_DELAY_MAX_US, BusConfig, FaultsConfig, FirmwareConfig,
                                   GaitConfig, Runtime, ScenarioInfo, WorldConfig, WorldKind,
                                   check_duration)
from protocol.errors import UserError

SCHEMA: dict[str, dict[str, type]] = {
    "scenario": {"name": str, "description": str, "seed": int, "duration_s": float},
    "bus": {"servos": int, "first_id": int, "baud": int, "echo": bool, "return_delay_us": int,
            "edition": str, "eeprom_busy_us": int, "sensor_node": bool, "sensor_node_id": int,
            "model": str},
    "firmware": {"cycle_hz": float, "tactile": bool, "python": str, "servo_lost_s": float,
                 "reads_per_cycle": int},
    "gait": {"name": str, "period_s": float, "step_length_m": float, "step_height_m": float,
             "max_obstacle_height_m": float, "direction_deg": float, "distance_m": float},
    "faults": {"bit_error_rate": float, "drop_status_rate": float, "can_drop_rate": float,
               "unplug": list,
               "stall": list, "overheat": list, "voltage_sag": list,
               # issue 42's vocabulary (hil/servobus/faults.py checks each entry)
               "brownout": list, "overload": list, "position_stuck": list,
               "position_noise": list, "id_conflict": list, "switch_stuck": list,
               "switch_bounce": list, "can_silent": list, "can_garbage": list,
               "force_bias": list, "force_dropout": list},
    "world": {"kind": str, "terrain": str, "density": str, "height_class": str,
              "obstacles": list, "length_m": float, "friction": float, "terrain_seed": int,
              # "ideal" (default: regression) or "real" (experiments): hil/world/fidelity.py
              "model": str, "obstacle_body": str, "units_seed": int},
    # Seed 000 (world.kind = "beams"): the two beams (Sec. II-B) and the force sensor (Eq. 6).
    "beams": {"k1_nm_per_rad": float, "k2_nm_per_rad": float, "hb1_m": float, "hb2_m": float,
              "noise": float, "preload_nm": float, "mass_kg": float},
    # Seed 000's host side: push, sense, estimate, plan and track (Sec. III).
    "traversal": {"strategy": str, "fx_n": float, "delay_ms": float, "sensing_ms": float,
                  "unknowns": int, "method": str, "max_time_s": float},
}


def _type_name(t: type) -> str:
    return {str: "a string", int: "an integer", float: "a number", bool: "true or false",
            list: "a list", dict: "a table"}.get(t, t.__name__)


def _check_type(where: str, section: str, key: str, value: Any, want: type) -> Any:
    if want is float and isinstance(value, (int, float)) and not isinstance(value, bool):
        if not math.isfinite(value):
            raise UserError(f"{where}: key '{section}.{key}' must be a finite number, got {value}")
        return float(value)
    if not isinstance(value, want) or (want is int and isinstance(value, bool)):
        raise UserError(f"{where}: key '{section}.{key}' must be {_type_name(want)}, "
                        f"got {type(value).__name__} {value!r}")
    return value


@dataclass(frozen=True)
class Scenario:
    """A checked scenario: its typed sections, every default applied (hil/scenario/sections.py),
    and the data as written (``data``, each section present; what the worlds and the
    firmware's hello read) with the file's ``text`` when it came from one."""

    path: str
    scenario: ScenarioInfo
    bus: BusConfig
    firmware: FirmwareConfig
    gait: GaitConfig
    faults: FaultsConfig
    world: WorldConfig
    beams: BeamsConfig
    traversal: TraversalConfig
    data: dict[str, Any] = field(repr=False, compare=False)
    text: str | None = field(default=None, repr=False, compare=False)

    @property
    def name(self) -> str:
        return self.scenario.name or Path(self.path).stem

    def as_toml_data(self) -> dict[str, Any]:
        """The sections as written, without the loader's ``_path`` (for a trace's metadata)."""
        return {k: v for k, v in self.data.items() if not k.startswith("_")}


def _sections(data: dict[str, Any], where: str) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for section, body in data.items():
        if section == "_path":
            continue
        if section not in SCHEMA:
            raise UserError(f"{where}: unknown section '[{section}]' "
                            f"(known: {', '.join(sorted(SCHEMA))})")
        if not isinstance(body, dict):
            raise UserError(f"{where}: '{section}' must be a table ([{section}])")
        keys = SCHEMA[section]
        out[section] = {}
        for key, value in body.items():
            if key not in keys:
                raise UserError(f"{where}: unknown key '{section}.{key}' "
                                f"(known: {', '.join(sorted(keys))})")
            out[section][key] = _check_type(where, section, key, value, keys[key])
    for section in SCHEMA:
        out.setdefault(section, {})
    out["_path"] = where
    return out


def parse(data: dict[str, Any], path: str | Path | None = None,
          text: str | None = None) -> Scenario:
    """Every key, type, default and rule of a scenario (a dict as TOML reads it)."""
    if isinstance(data, Scenario):
        return data
    where = str(path if path is not None else data.get("_path", "scenario"))
    d = _sections(data, where)
    world = WorldConfig.parse(where, d["world"])
    return Scenario(
        where, ScenarioInfo.parse(where, d["scenario"]), BusConfig.parse(where, d["bus"]),
        FirmwareConfig.parse(where, d["firmware"]), GaitConfig.parse(where, d["gait"]),
        FaultsConfig.parse(where, d["faults"]), world,
        BeamsConfig.parse(where, d["beams"], world.kind is WorldKind.BEAMS),
        TraversalConfig.parse(where, d["traversal"]), d, text)


def check(data: dict[str, Any], path: str | Path | None = None) -> dict[str, Any]:
    """``parse``'s checked data: every section present, as written."""
    return parse(data, path).data


def from_text(text: str, path: str | Path) -> Scenario:
    """A scenario from its TOML ``text`` (a trace's metadata keeps it); ``path`` names it."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise UserError(f"{path}: not valid TOML: {exc}") from None
    return parse(data, path, text)


def load_scenario(path: str | Path) -> Scenario:
    """Read and check a scenario file."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise UserError(f"{p}: scenario file not found") from None
    except (IsADirectoryError, PermissionError, UnicodeDecodeError) as exc:
        raise UserError(f"{p}: cannot read scenario ({exc.__class__.__name__})") from None
    return from_text(text, p)


def load(path: str | Path) -> dict[str, Any]:
    """A scenario file's checked data (``load_scenario(path).data``)."""
    return load_scenario(path).data


__all__ = ["SCHEMA", "Scenario", "ScenarioInfo", "BusConfig", "FirmwareConfig", "GaitConfig",
           "FaultsConfig", "WorldConfig", "BeamsConfig", "TraversalConfig", "Runtime",
           "WorldKind", "GAITS", "DEFAULT_BAUD", "DEFAULT_DURATION_S", "MAX_DURATION_S",
           "RETURN_DELAY_MAX_US", "check_duration", "parse", "check",
           "from_text", "load_scenario", "load"]
