"""Expectation files (TOML): a case (which scenario, how long, which seed) and what its run
must show (``[[expect]]`` tables), loaded into frozen dataclasses with one-line errors.

The format is documented for users in docs/testing.md; ``KEYS`` below is its one schema:
every kind's keys, their types, which are required. A malformed file raises ``UserError``
naming the file and the key (exit 2), before anything runs.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path
from typing import Any

from hexhil.hil import scenario as scenario_mod
from hexhil.hil.scenario import Scenario, WorldKind, read_toml_file, toml_data
from hexhil.hil.scenario.rules import check_table, optional, typed
from hexhil.hil.link.firmware_process import IN_PROCESS, RUNTIMES
from hexhil.hil.scenario.faults_section import FaultKind
from hexhil.hil.servobus.master_check import KINDS as VIOLATION_KINDS
from hexhil.hil.link.served_firmware import served_firmware
from hexhil.hil.mcu.flash_fs import FlashFiles
from hexhil.expect.signal_fields import check_signal_field
from hexhil.protocol import can_frames
from hexhil.protocol.errors import BadValue, UserError


class Kind(str, Enum):
    """What an expectation measures (the ``kind`` key)."""

    DISPLACEMENT = "displacement"      # body displacement in the start heading's frame
    HEADING = "heading"                # direction of travel over the window
    POSE = "pose"                      # world pose at the window's end
    SPEED = "speed"                    # mean walking speed over the window
    TACTILE_RULE = "tactile_rule"      # seed 003 Eq. 6-7 after each switch press
    PROTOCOL = "protocol"              # the master's protocol violations (hil/servobus/master_check.py)
    FAULT_RESPONSE = "fault_response"  # safe stop or ride-through after an injected fault
    CAN = "can"                        # a DBC frame's rate and signal ranges
    SERVO_LIMITS = "servo_limits"      # temperature, load, voltage never out of range
    NO_EXCEPTION = "no_exception"      # the firmware raised nothing
    SIGNAL = "signal"                  # any topic's field, a statistic, a range
    DEADLINE = "deadline"              # an ELF's busy time per control cycle (hil/mcu/deadline.py)


class Stat(str, Enum):
    """The statistic of a ``signal`` expectation."""

    MIN = "min"
    MAX = "max"
    MEAN = "mean"
    AT = "at"          # the last value at or before ``at_s``
    EDGES = "edges"    # how many times the value changed
    COUNT = "count"    # how many messages


FAULTS = (*(k.value for k in FaultKind), "bit_error", "drop_status")   # the timed kinds
RESPONSES = ("safe_stop", "ride_through")
RUNTIME_CHOICES = (*RUNTIMES, IN_PROCESS)


@dataclass(frozen=True)
class Range:
    """Inclusive limits; None on a side means unbounded."""

    low: float | None = None
    high: float | None = None

    def holds(self, value: float) -> bool:
        return ((self.low is None or value >= self.low)
                and (self.high is None or value <= self.high))

    def __str__(self) -> str:
        if self.low is not None and self.high is not None:
            return f"[{self.low:g}, {self.high:g}]"
        return f">= {self.low:g}" if self.low is not None else f"<= {self.high:g}"


# kind -> key -> (type, required). "range" keys take [low, high] or {min = .., max = ..}.
_RANGE = "range"
KEYS: dict[Kind, dict[str, tuple[Any, bool]]] = {
    Kind.DISPLACEMENT: {"dx_m": (_RANGE, False), "dy_m": (_RANGE, False),
                        "dyaw_deg": (_RANGE, False)},
    Kind.HEADING: {"direction_deg": (_RANGE, True)},
    Kind.POSE: {"x_m": (_RANGE, False), "y_m": (_RANGE, False), "z_m": (_RANGE, False),
                "yaw_deg": (_RANGE, False)},
    Kind.SPEED: {"min_m_s": (float, True), "max_m_s": (float, False)},
    Kind.TACTILE_RULE: {"h_tolerance_m": (float, False), "l_tolerance_m": (float, False),
                        "min_steps": (int, False), "min_press_s": (float, False),
                        "max_obstacle_height_m": (float, False)},
    Kind.PROTOCOL: {"allow": (list, False)},
    Kind.FAULT_RESPONSE: {"fault": (str, True), "response": (str, True),
                          "within_s": (float, True)},
    Kind.CAN: {"message": (str, True), "rate_hz": (_RANGE, False), "signals": (dict, False)},
    Kind.SERVO_LIMITS: {"temperature_c": (_RANGE, False), "load_frac": (_RANGE, False),
                        "voltage_v": (_RANGE, False), "ids": (list, False)},
    Kind.NO_EXCEPTION: {},
    Kind.SIGNAL: {"topic": (str, True), "field": (str, True), "stat": (str, True),
                  "at_s": (float, False), "limit": (_RANGE, True)},
    Kind.DEADLINE: {"max_busy_ms": (float, True), "stat": (str, False),
                    "max_late": (int, False)},
}
BUSY_STATS = ("p50", "p99", "max")     # a deadline expectation's statistic of busy time
COMMON_KEYS = ("name", "kind", "window_s")
AT_LEAST_ONE = (Kind.DISPLACEMENT, Kind.POSE, Kind.SERVO_LIMITS)
CASE_KEYS: dict[str, type] = {"name": str, "scenario": str, "duration_s": float, "seed": int,
                              "tactile": bool, "python": str, "firmware": str, "send": list,
                              "main": str, "fs": str, "masked_limit_s": float}
TACTILE_DEFAULTS = {"h_tolerance_m": 0.01, "l_tolerance_m": 0.015, "min_steps": 1,
                    "min_press_s": 0.04}


@dataclass(frozen=True)
class Expectation:
    """One ``[[expect]]`` table: its name, kind, window and checked keys."""

    name: str
    kind: Kind
    window_s: tuple[float, float | None] = (0.0, None)
    values: tuple[tuple[str, Any], ...] = ()

    def get(self, key: str, default: Any = None) -> Any:
        for k, v in self.values:
            if k == key:
                return v
        return default

    def ranges(self) -> list[tuple[str, Range]]:
        return [(k, v) for k, v in self.values if isinstance(v, Range)]


@dataclass(frozen=True)
class Case:
    """A run to make (scenario, seed, duration, firmware settings) and what it must show."""

    name: str
    path: Path
    scenario: Scenario = field(hash=False)
    seed: int
    duration_s: float
    tactile: bool | None
    python: str
    expectations: tuple[Expectation, ...]
    sends: tuple[tuple[int, int, bytes], ...] = ()   # (t_us, arbitration id, data) from the host
    firmware: str | None = None   # a firmware of the user's (hexhil run --firmware), not ours
    flash_files: FlashFiles | None = None   # a MicroPython ELF's /flash (--main, --fs)
    masked_limit_s: float | None = None     # an ELF's masked-spin limit (--masked-limit)


def _range(where: str, value: Any) -> Range:
    if isinstance(value, dict):
        unknown = set(value) - {"min", "max"}
        lo, hi = value.get("min"), value.get("max")
        if unknown or (lo is None and hi is None):
            raise BadValue(f"{where} must be [low, high] or {{min = .., max = ..}}, got {value!r}")
    elif isinstance(value, (list, tuple)) and len(value) == 2:
        lo, hi = value
    else:
        raise BadValue(f"{where} must be [low, high] or {{min = .., max = ..}}, got {value!r}")
    for v in (lo, hi):
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float))
                              or not math.isfinite(v)):
            raise BadValue(f"{where} limits must be finite numbers, got {value!r}")
    if lo is not None and hi is not None and lo > hi:
        raise BadValue(f"{where} low {lo} is above high {hi}")
    return Range(None if lo is None else float(lo), None if hi is None else float(hi))


def _as_is(what: str, value: Any) -> Any:
    return value


def _window(where: str, value: Any) -> tuple[float, float | None]:
    r = _range(where, value)
    start = r.low if r.low is not None else 0.0
    if start < 0:
        raise BadValue(f"{where} must start at 0 s or later, got {value!r}")
    return start, r.high


def _check_kind(where: str, kind: Kind, values: dict[str, Any]) -> None:
    """Rules between a kind's keys (the types are checked already)."""
    if kind in AT_LEAST_ONE and not values:
        raise BadValue(f"{where}: kind '{kind.value}' needs at least one of "
                       f"{', '.join(k for k in KEYS[kind] if k != 'ids')}")
    if kind is Kind.PROTOCOL:
        for v in values.get("allow", []):
            if v not in VIOLATION_KINDS:
                raise BadValue(f"{where}: key 'allow': {v!r} is not a violation kind "
                               f"({', '.join(VIOLATION_KINDS)})")
    if kind is Kind.FAULT_RESPONSE:
        if values["fault"] not in FAULTS:
            raise BadValue(f"{where}: key 'fault' must be one of {', '.join(FAULTS)}, "
                           f"got {values['fault']!r}")
        if values["response"] not in RESPONSES:
            raise BadValue(f"{where}: key 'response' must be one of {', '.join(RESPONSES)}, "
                           f"got {values['response']!r}")
    if kind is Kind.CAN:
        signals = values.get("signals", {})
        values["signals"] = tuple((k, _range(f"{where}: key 'signals.{k}'", v))
                                  for k, v in sorted(signals.items()))
    if kind is Kind.DEADLINE and values.get("stat", "max") not in BUSY_STATS:
        raise BadValue(f"{where}: key 'stat' must be one of {', '.join(BUSY_STATS)}, "
                       f"got {values['stat']!r}")
    if kind is Kind.SIGNAL:
        if values["stat"] not in [s.value for s in Stat]:
            raise BadValue(f"{where}: key 'stat' must be one of "
                           f"{', '.join(s.value for s in Stat)}, got {values['stat']!r}")
        values["stat"] = Stat(values["stat"])
        if values["stat"] is Stat.AT and "at_s" not in values:
            raise BadValue(f"{where}: stat 'at' needs key 'at_s'")
    for key in ("within_s", "min_m_s", "h_tolerance_m", "l_tolerance_m", "min_press_s"):
        if key in values and values[key] < 0:
            raise BadValue(f"{where}: key '{key}' must be 0 or more, got {values[key]}")


def expectation(where: str, raw: Any, index: int = 0) -> Expectation:
    """One ``[[expect]]`` table, checked (``where`` and ``index`` name it in errors)."""
    if not isinstance(raw, dict):
        raise BadValue(f"{where}: each [[expect]] must be a table")
    name = raw.get("name")
    label = f"{where}: expect[{index}]" + (f" ({name!r})" if isinstance(name, str) else "")
    if not isinstance(name, str) or not name:
        raise BadValue(f"{label}: key 'name' is required (a string)")
    if "kind" not in raw:
        raise BadValue(f"{label}: key 'kind' is required ({', '.join(k.value for k in Kind)})")
    try:
        kind = Kind(raw["kind"])
    except ValueError:
        raise BadValue(f"{label}: key 'kind' must be one of "
                       f"{', '.join(k.value for k in Kind)}, got {raw['kind']!r}") from None
    fields = {**{k: (_range if want == _RANGE else want, required)
                 for k, (want, required) in KEYS[kind].items()},
              **{k: (_as_is, False) for k in COMMON_KEYS}}
    values = {k: v for k, v in check_table(label, raw, fields, context=f" for kind '{kind.value}'")
              .items() if k not in COMMON_KEYS}
    _check_kind(label, kind, values)
    window = _window(f"{label}: key 'window_s'", raw["window_s"]) if "window_s" in raw \
        else (0.0, None)
    if kind is Kind.TACTILE_RULE:
        values = {**TACTILE_DEFAULTS, **values}
    if kind is Kind.SIGNAL:
        check_signal_field(label, values["topic"], values["field"])
    return Expectation(name, kind, window, tuple(sorted(values.items())))


def _sends(where: str, raw: list[Any]) -> tuple[tuple[int, int, bytes], ...]:
    """``case.send``: CAN frames (by DBC name, SI signal values) the host sends at a time."""
    out = []
    for i, e in enumerate(raw):
        key = f"case.send[{i}]"
        label = f"{where}: key '{key}'"
        if not isinstance(e, dict) or set(e) - {"at_s", "message", "signals"} \
                or "at_s" not in e or "message" not in e:
            raise BadValue(f"{label} must be a table {{at_s = .., message = .., "
                           f"signals = {{..}}}}, got {e!r}")
        at_s = typed(f"{where}: key '{key}.at_s'", e["at_s"], float)
        if at_s < 0:
            raise BadValue(f"{where}: key '{key}.at_s' must be 0 or more, got {at_s}")
        signals = typed(f"{where}: key '{key}.signals'", e.get("signals", {}), dict)
        message = typed(f"{where}: key '{key}.message'", e["message"], str)
        try:
            arb_id, data = can_frames.encode(message, **signals)
        except (ValueError, TypeError, OverflowError) as exc:
            raise BadValue(f"{label}: {exc}") from None
        out.append((int(round(at_s * 1e6)), arb_id, bytes(data)))
    return tuple(sorted(out))


def _scenario(where: str, path: Path, data: dict[str, Any]) -> Scenario:
    """The case's scenario: the file ``case.scenario`` names (relative to this file), or
    the scenario sections written in this file itself."""
    inline = {k: v for k, v in data.items() if k not in ("case", "expect")}
    ref = data.get("case", {}).get("scenario")
    if ref is not None and inline:
        raise BadValue(f"{where}: key 'case.scenario' names a scenario, so this file cannot "
                       f"also hold scenario sections ({', '.join(sorted(inline))})")
    if ref is not None:
        return scenario_mod.load_scenario(path.parent / ref)
    if not inline:
        raise BadValue(f"{where}: key 'case.scenario' is required (or write the scenario's "
                       f"sections in this file)")
    return scenario_mod.parse(inline, path)


def check_windows(where: str, expectations: tuple[Expectation, ...], duration_s: float,
                  servos: int) -> None:
    """Each expectation looks inside the run: its window (and a signal's ``at_s``) within
    ``duration_s``, a ``/servos`` index below the bus's ``servos``; else one line, before
    anything runs."""
    for i, e in enumerate(expectations):
        label = f"{where}: expect[{i}] ({e.name!r})"
        t0, t1 = e.window_s
        if t0 >= duration_s or (t1 is not None and t1 > duration_s):
            raise BadValue(f"{label}: key 'window_s' [{t0:g}, {'end' if t1 is None else f'{t1:g}'}]"
                           f" reaches past the run's end ({duration_s:g} s)")
        if e.kind is not Kind.SIGNAL:
            continue
        if e.get("at_s") is not None and not 0 <= e.get("at_s") <= duration_s:
            raise BadValue(f"{label}: key 'at_s' {e.get('at_s'):g} is outside the run "
                           f"(0-{duration_s:g} s)")
        if e.get("topic") == "/servos":
            for index in re.findall(r"servos\[(-?\d+)\]", e.get("field")):
                if not -servos <= int(index) < servos:
                    raise BadValue(f"{label}: key 'field': servos[{index}] is out of range "
                                   f"(the bus has {servos} servos: 0-{servos - 1})")


def hexapod(where: str, sc: Scenario) -> Scenario:
    """``sc``, if its world is the hexapod's (the firmware's): else one line."""
    if sc.world.kind not in (None, WorldKind.HEXAPOD):
        raise BadValue(f"{where}: key 'world.kind': hexhil test runs the hexapod firmware, "
                       f"this scenario's world is {sc.world.kind.value}")
    return sc


def load(path: str | Path) -> Case:
    """Read and check one expectation file."""
    p = Path(path)
    data = toml_data(read_toml_file(p, "expectation"), p)
    where = str(p)
    case = data.get("case", {})
    if not isinstance(case, dict):
        raise BadValue(f"{where}: 'case' must be a table ([case])")
    check_table(where, case, optional(CASE_KEYS), "case.")
    raw = data.get("expect")
    if not isinstance(raw, list) or not raw:
        raise BadValue(f"{where}: key 'expect' is required: one [[expect]] table or more")
    expectations = tuple(expectation(where, e, i) for i, e in enumerate(raw))
    names = [e.name for e in expectations]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise BadValue(f"{where}: key 'expect.name': {dup[0]!r} is used twice")
    sc = hexapod(where, _scenario(where, p, data))
    for i, e in enumerate(expectations):
        if e.kind is Kind.TACTILE_RULE and e.get("max_obstacle_height_m") is None \
                and sc.gait.max_obstacle_height_m is None:
            raise BadValue(f"{where}: expect[{i}] ({e.name!r}): key 'max_obstacle_height_m' "
                           f"is required (H of Eq. 7: the scenario's gait does not give it)")
    duration = scenario_mod.check_duration(case.get("duration_s", sc.scenario.duration_s),
                                           f"{where}: key 'case.duration_s'")
    check_windows(where, expectations, duration, sc.bus.servos)
    python = case.get("python", sc.firmware.python.value)
    if python not in RUNTIME_CHOICES:
        raise BadValue(f"{where}: key 'case.python' must be one of "
                       f"{', '.join(RUNTIME_CHOICES)}, got {python!r}")
    firmware = case.get("firmware")
    if firmware is not None:
        if "python" in case:
            raise UserError(f"{where}: key 'case.firmware' brings its own runtime: leave out "
                            "'case.python'")
        if "tactile" in case:
            raise UserError(f"{where}: key 'case.tactile' sets our firmware's obstacle rule: "
                            "the case's firmware reads no such setting")
        firmware = str(p.parent / firmware)
    flash = None
    if "main" in case or "fs" in case:
        if firmware is None:
            raise UserError(f"{where}: keys 'case.main' and 'case.fs' need a MicroPython "
                            "STM32F411 ELF as 'case.firmware'")
        flash = FlashFiles(*(p.parent / case[k] if k in case else None for k in ("main", "fs")))
    masked = case.get("masked_limit_s")
    if masked is not None and not masked > 0:
        raise BadValue(f"{where}: key 'case.masked_limit_s' must be above 0 s, got {masked}")
    if firmware is not None:
        served_firmware(firmware, f"{where}: key 'case.firmware'", flash_files=flash)  # checked now
    return Case(name=case.get("name", p.stem), path=p, scenario=sc, firmware=firmware,
                flash_files=flash, masked_limit_s=masked,
                seed=scenario_mod.check_seed(case.get("seed", sc.scenario.seed),
                                             f"{where}: key 'case.seed'"),
                duration_s=duration,
                tactile=case.get("tactile"), python=python, expectations=expectations,
                sends=_sends(where, case.get("send", [])))
