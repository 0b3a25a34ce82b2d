"""The scenario's keys and their types, and the checks every table a user writes goes
through: one table checker (unknown keys, missing keys, types, finite numbers; on
protocol/schema.py's kinds) and the range rules the sections share, so a rule and its
one-line error are written once."""
from __future__ import annotations

import math
from typing import Any, Callable, Mapping, Union

from hexhil.protocol import schema
from hexhil.protocol.errors import BadValue

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
               "unplug": list, "stall": list, "overheat": list, "voltage_sag": list,
               # the named failures (hil/scenario/faults_section.py types each entry)
               "brownout": list, "overload": list, "position_stuck": list,
               "position_noise": list, "id_conflict": list, "switch_stuck": list,
               "switch_bounce": list, "switch_swing_press": list, "can_silent": list,
               "can_garbage": list,
               "force_bias": list, "force_dropout": list,
               # the bus fuzzer's (docs/fuzzing.md): status packets and CAN frames mangled
               **{k: list for k in ("status_checksum", "status_wrong_id", "status_truncated",
                                    "status_padded", "status_error", "status_late",
                                    "status_missing", "status_twin", "can_dropped",
                                    "can_delayed", "can_reordered", "can_corrupt")}},
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

_KIND = {str: "str", int: "int", float: "number", bool: "bool", list: "list", dict: "table"}
_SAID = {str: "a string", int: "an integer", float: "a number", bool: "true or false",
         list: "a list", dict: "a table"}
# A key's type, or a converter given (what, value) that returns the value or raises.
Want = Union[type, Callable[[str, Any], Any]]


def typed(what: str, value: Any, want: Want) -> Any:
    """``value`` as ``want`` says: floats from integers and finite, or a one-line error
    naming ``what``."""
    if not isinstance(want, type):
        return want(what, value)
    if not schema.is_kind(value, _KIND[want]):
        raise BadValue(f"{what} must be {_SAID[want]}, got {type(value).__name__} {value!r}")
    if want is float:
        if not math.isfinite(value):
            raise BadValue(f"{what} must be a finite number, got {value}")
        return float(value)
    return value


def check_table(where: str, raw: Mapping[str, Any], fields: Mapping[str, tuple[Want, bool]],
                prefix: str = "", context: str = "") -> dict[str, Any]:
    """``raw``'s keys checked against ``fields`` (key -> (type, required)) and converted.
    Errors name ``where``, the key as ``prefix + key``, and end in ``context`` (e.g.
    " in a 'stall' entry")."""
    kinds = {k: (_KIND[w] if isinstance(w, type) else "any", req)
             for k, (w, req) in fields.items()}
    for key, what in schema.problems(raw, kinds):
        if what == schema.UNKNOWN:
            raise BadValue(f"{where}: unknown key '{prefix}{key}'{context} "
                           f"(known: {', '.join(sorted(fields))})")
        if what == schema.MISSING:
            raise BadValue(f"{where}: key '{prefix}{key}' is required{context}")
        typed(f"{where}: key '{prefix}{key}'", raw[key], fields[key][0])   # raises
    return {k: typed(f"{where}: key '{prefix}{k}'", v, fields[k][0]) for k, v in raw.items()}


def optional(types: Mapping[str, type]) -> dict[str, tuple[Want, bool]]:
    """Fields of ``types``, none of them required (a scenario section's)."""
    return {k: (t, False) for k, t in types.items()}


# --- range rules: each section's parse states its numbers' ranges with these; the CLI's and
# the API's numbers go through them too (a flag's or an argument's value need not be a finite
# number: each rule refuses what is not one). ``params``: the API parameters ``what`` names.
def _real(what: str, value: Any, params: tuple[str, ...]) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise BadValue(f"{what} must be a number, got {type(value).__name__} {value!r}",
                       params=params)


def positive(what: str, value: float, params: tuple[str, ...] = ()) -> float:
    _real(what, value, params)
    if not value > 0:
        raise BadValue(f"{what} must be positive, got {value}", params=params)
    return value


def at_least(what: str, value: float, low: float, params: tuple[str, ...] = ()) -> float:
    _real(what, value, params)
    if not low <= value < math.inf:
        raise BadValue(f"{what} must be {'0' if low == 0 else low} or more, got {value}",
                       params=params)
    return value


def within(what: str, value: float, low: float, high: float, high_open: bool = False,
           low_open: bool = False, params: tuple[str, ...] = ()) -> float:
    """``low <= value <= high`` (``< high`` with ``high_open``, ``low <`` with
    ``low_open``); NaN and infinities are outside every range."""
    _real(what, value, params)
    above = low < value if low_open else low <= value
    below = value < high if high_open else value <= high
    if not (above and below):
        raise BadValue(f"{what} must be in {'(' if low_open else '['}{low:g}, {high:g}"
                       f"{')' if high_open else ']'}, got {value}", params=params)
    return value


def one_of(what: str, value: Any, choices: tuple[Any, ...]) -> Any:
    if value not in choices:
        raise BadValue(f"{what} must be one of {', '.join(map(str, choices))}, got {value!r}")
    return value
