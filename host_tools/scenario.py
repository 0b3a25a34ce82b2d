"""Scenario files (TOML): one loader, one schema, one-line errors that name file and key.

Each section's keys and types are declared in ``SCHEMA``; a module that adds a scenario
feature adds its keys here, so an unknown or mistyped key is always caught in one place.
``float`` keys accept integers; ``list`` keys are checked further by their owner.
"""
from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from protocol.errors import UserError

SCHEMA: dict[str, dict[str, type]] = {
    "scenario": {"name": str, "description": str, "seed": int, "duration_s": float},
    "bus": {"servos": int, "first_id": int, "baud": int, "echo": bool, "return_delay_us": int,
            "edition": str, "eeprom_busy_us": int},
    "firmware": {"cycle_hz": float, "tactile": bool, "python": str, "servo_lost_s": float,
                 "reads_per_cycle": int},
    "gait": {"name": str, "period_s": float, "step_length_m": float, "step_height_m": float,
             "max_obstacle_height_m": float, "direction_deg": float, "distance_m": float},
    "faults": {"bit_error_rate": float, "drop_status_rate": float, "unplug": list,
               "stall": list, "overheat": list, "voltage_sag": list},
    "world": {"kind": str, "terrain": str, "density": str, "height_class": str,
              "obstacles": list, "length_m": float, "friction": float, "terrain_seed": int},
}


def _type_name(t: type) -> str:
    return {str: "a string", int: "an integer", float: "a number", bool: "true or false",
            list: "a list", dict: "a table"}.get(t, t.__name__)


def _check(path: Path, section: str, key: str, value: Any, want: type) -> Any:
    if want is float and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if want is int and isinstance(value, bool):
        ok = False
    else:
        ok = isinstance(value, want)
    if not ok:
        raise UserError(f"{path}: key '{section}.{key}' must be {_type_name(want)}, "
                        f"got {type(value).__name__} {value!r}")
    return value


def validate(data: dict[str, Any], path: Path) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for section, body in data.items():
        if section not in SCHEMA:
            raise UserError(f"{path}: unknown section '[{section}]' "
                            f"(known: {', '.join(sorted(SCHEMA))})")
        if not isinstance(body, dict):
            raise UserError(f"{path}: '{section}' must be a table ([{section}])")
        keys = SCHEMA[section]
        out[section] = {}
        for key, value in body.items():
            if key not in keys:
                raise UserError(f"{path}: unknown key '{section}.{key}' "
                                f"(known: {', '.join(sorted(keys))})")
            out[section][key] = _check(path, section, key, value, keys[key])
    return out


def load(path: str | Path) -> dict[str, Any]:
    """Read and validate a scenario; every section is present (possibly empty)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise UserError(f"{p}: scenario file not found") from None
    except (IsADirectoryError, PermissionError, UnicodeDecodeError) as exc:
        raise UserError(f"{p}: cannot read scenario ({exc.__class__.__name__})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise UserError(f"{p}: not valid TOML: {exc}") from None
    out = validate(data, p)
    for section in SCHEMA:
        out.setdefault(section, {})
    out["_path"] = str(p)
    return out
