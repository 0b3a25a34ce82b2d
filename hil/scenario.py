"""Scenario files (TOML): one loader, one schema, one set of rules, one-line errors.

Each section's keys and types are declared in ``SCHEMA``, and every rule on a value that
more than one owner relies on (the bus, the gait, durations) is checked in ``check``, so
``hexhil run``, ``hexhil bus`` and the tests build the same rig from the same file.
``float`` keys accept integers; ``list`` keys are checked further by their owner
(faults, terrain). ``load`` reads a file; ``check`` takes a dict (tests build them).
"""
from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any

from protocol import ax12, xl430
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
               "stall": list, "overheat": list, "voltage_sag": list},
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
DEFAULT_DURATION_S = 30.0
WORLD_KINDS = ("hexapod", "beams")
GAITS = ("tripod", "wave")
RETURN_DELAY_MAX_US = 508       # AX-12 register 5: 2 us a unit, 0-254
BAUD_TOLERANCE = 0.03           # AX-12 e-manual: a line within 3 % of the servo's rate decodes


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


SERVO_MODELS = ("ax-12a", xl430.MODEL_NAME)  # Protocol 1.0, Protocol 2.0


def baud_register(baud: int) -> int:
    """The AX-12 Baud Rate register (2 Mbps / (n + 1)) nearest ``baud`` bps."""
    return min(254, max(0, round(2_000_000 / baud) - 1))


def _check_bus(where: str, bus: dict[str, Any]) -> None:
    n, first = bus.get("servos", 18), bus.get("first_id", 1)
    if n < 1 or first < 0 or first + n - 1 > 253:
        raise UserError(f"{where}: servos {n} from ID {first} do not fit IDs 0-253")
    baud = bus.get("baud", 1_000_000)
    if baud <= 0:
        raise UserError(f"{where}: key 'bus.baud' must be positive, got {baud}")
    model = bus.get("model", SERVO_MODELS[0])
    if model not in SERVO_MODELS:
        raise UserError(f"{where}: key 'bus.model' must be one of {', '.join(SERVO_MODELS)}, "
                        f"got {model!r}")
    if model != SERVO_MODELS[0]:
        if baud not in xl430.BAUD_BPS or first + n - 1 > 252 or bus.get("sensor_node"):
            raise UserError(f"{where}: an {model} bus needs a baud of "
                            f"{'/'.join(map(str, xl430.BAUD_BPS))}, IDs 0-252, no sensor node")
    elif abs(ax12.baud_to_bps(baud_register(baud)) - baud) > BAUD_TOLERANCE * baud:
        raise UserError(f"{where}: baud {baud}: no AX-12 rate 2000000/(n+1) within 3 % of it")
    edition = bus.get("edition", ax12.EDITION_EMANUAL)
    if edition not in ax12.EDITIONS:
        raise UserError(f"{where}: key 'bus.edition' must be one of {', '.join(ax12.EDITIONS)}, "
                        f"got {edition!r}")
    rd = bus.get("return_delay_us")
    if rd is not None and (rd % 2 or not 0 <= rd <= RETURN_DELAY_MAX_US):
        raise UserError(f"{where}: key 'bus.return_delay_us' must be even and "
                        f"0-{RETURN_DELAY_MAX_US}, got {rd}")
    node = bus.get("sensor_node_id")
    if node is not None and (not 0 <= node <= 253 or first <= node < first + n):
        raise UserError(f"{where}: key 'bus.sensor_node_id' must be 0-253 and no servo's ID, "
                        f"got {node}")
    busy = bus.get("eeprom_busy_us", 0)
    if busy < 0:
        raise UserError(f"{where}: key 'bus.eeprom_busy_us' must be 0 or more, got {busy}")


def _check_values(where: str, sc: dict[str, Any]) -> None:
    _check_bus(where, sc["bus"])
    duration = sc["scenario"].get("duration_s", DEFAULT_DURATION_S)
    if not duration > 0:
        raise UserError(f"{where}: key 'scenario.duration_s' must be positive, got {duration}")
    name = sc["gait"].get("name", GAITS[0])
    if name not in GAITS:
        raise UserError(f"{where}: key 'gait.name' must be tripod or wave, got {name!r}")
    for section, key in (("firmware", "cycle_hz"), ("gait", "period_s")):
        if not sc[section].get(key, 1.0) > 0:
            raise UserError(f"{where}: '{key}' must be positive")
    drop = sc["faults"].get("can_drop_rate", 0.0)
    if not 0.0 <= drop <= 1.0:
        raise UserError(f"{where}: key 'faults.can_drop_rate' must be in [0, 1], got {drop}")
    kind = sc["world"].get("kind", WORLD_KINDS[0])
    if sc["world"] and kind not in WORLD_KINDS:
        raise UserError(f"{where}: key 'world.kind' must be one of {', '.join(WORLD_KINDS)}, "
                        f"got {kind!r}")


def check(data: dict[str, Any], path: str | Path | None = None) -> dict[str, Any]:
    """Every key and shared rule of a scenario; returns it with every section present."""
    where = str(path if path is not None else data.get("_path", "scenario"))
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
    _check_values(where, out)
    return out


def load(path: str | Path) -> dict[str, Any]:
    """Read and check a scenario file."""
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
    return check(data, p)
