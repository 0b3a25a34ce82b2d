"""What a run measured against its expectations: read the trace (and the run summary) once,
then one function a kind turns the recording into an ``Outcome``: measured value, limit,
pass or fail, and the moment it failed (written into a kept trace, host_tools/expect/case_runs.py).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, NamedTuple

from hexhil.hil.run_result import BodyDisplacement
from hexhil.expect import steps as steps_mod
from hexhil.expect.spec import Case, Expectation, Kind, Range, Stat
from hexhil.trace import topics
from hexhil.trace.reader import Trace
from hexhil.protocol import hexapod
from hexhil.protocol.errors import BadValue

WALKING = 2  # protocol/can_frames.py STATE_WALKING, the heartbeat's state signal


@dataclass(frozen=True)
class Outcome:
    """One expectation's verdict on one run."""

    case: str
    name: str
    kind: str
    measured: str
    limit: str
    passed: bool
    t_s: float | None = None      # when it failed (or the value was taken), virtual time
    value: float | None = None    # the measured number, where there is one
    time_s: float = 0.0           # wall time its own evaluation took (JUnit testcase time)


class Pose(NamedTuple):
    t_s: float
    x_m: float
    y_m: float
    z_m: float
    yaw_rad: float


@dataclass
class Recording:
    """The decoded topics the expectations read, each as (t_s, message) lists."""

    end_s: float
    summary: dict[str, Any]
    messages: dict[str, list[tuple[float, dict[str, Any]]]] = field(default_factory=dict)

    def on(self, topic: str, start_s: float = 0.0, end_s: float | None = None
           ) -> list[tuple[float, dict[str, Any]]]:
        hi = self.end_s if end_s is None else end_s
        return [(t, m) for t, m in self.messages.get(topic, []) if start_s <= t <= hi]

    def poses(self) -> list[Pose]:
        out = []
        for t, m in self.messages.get(topics.T_BODY, []):
            p, q = m["translation"], m["rotation"]
            yaw = math.atan2(2 * (q["w"] * q["z"] + q["x"] * q["y"]),
                             1 - 2 * (q["y"] ** 2 + q["z"] ** 2))
            out.append(Pose(t, p["x"], p["y"], p["z"], yaw))
        return out


def topics_read(case: Case) -> frozenset[str]:
    """The topics ``case``'s expectations read: the kinds' own, each signal's, and, where
    a kind reads frames (``can``, ``fault_response``: the heartbeat) or a signal is on
    one, every ``/can/`` topic (``T_CAN_PREFIX`` in the set: ``reads``)."""
    signals = {e.get("topic") for e in case.expectations if e.kind is Kind.SIGNAL}
    can = any(e.kind in (Kind.CAN, Kind.FAULT_RESPONSE) for e in case.expectations) or any(
        t.startswith(topics.T_CAN_PREFIX) for t in signals)
    return frozenset({topics.T_BODY, topics.T_JOINTS, topics.T_SWITCHES, topics.T_FAULTS,
                      topics.T_VIOLATIONS, topics.T_SERVOS, *signals,
                      *((topics.T_CAN_PREFIX,) if can else ())})


def reads(topic: str, wanted: frozenset[str]) -> bool:
    """Whether a recording of the topics ``wanted`` (``topics_read``) holds ``topic``."""
    return topic in wanted or (topics.T_CAN_PREFIX in wanted
                               and topic.startswith(topics.T_CAN_PREFIX))


def read(path: Path, summary: dict[str, Any], wanted: frozenset[str]) -> Recording:
    """Every message on the topics ``wanted`` (``topics_read``)."""
    rec = Recording(end_s=float(summary.get("sim_time_s", 0.0)), summary=summary)
    with Trace(path) as tr:
        present = [t for t in tr.topics() if reads(t, wanted)]
        for m, value in tr.decoded(present):
            rec.messages.setdefault(m.topic, []).append((m.log_time_ns / 1e9, value))
    return rec


def _window(e: Expectation, rec: Recording) -> tuple[float, float]:
    start, end = e.window_s
    return start, min(rec.end_s, end) if end is not None else rec.end_s


def _pose_at(poses: list[Pose], t_s: float) -> Pose:
    before = [p for p in poses if p.t_s <= t_s]
    return before[-1] if before else poses[0]


def _ranges(e: Expectation, measured: dict[str, float]) -> tuple[str, str, bool, float]:
    """Several named values against their ranges: one measured/limit text."""
    parts, limits, ok, first = [], [], True, math.nan
    for key, r in e.ranges():
        v = measured[key]
        parts.append(f"{key} {v:+.4g}")
        limits.append(f"{key} {r}")
        if not r.holds(v):
            ok = False
            first = v if math.isnan(first) else first
        elif math.isnan(first):
            first = v
    return ", ".join(parts), ", ".join(limits), ok, first


def _body(e: Expectation, rec: Recording) -> tuple[str, str, bool, float | None, float | None]:
    poses = rec.poses()
    if not poses:
        return "no /body samples", "", False, None, None
    t0, t1 = _window(e, rec)
    p0, p1 = _pose_at(poses, t0), _pose_at(poses, t1)
    d = BodyDisplacement.between(p0, p1).as_dict()
    dt = max(p1.t_s - p0.t_s, 1e-9)
    if e.kind is Kind.DISPLACEMENT:
        values = d
    elif e.kind is Kind.HEADING:
        values = {"direction_deg": math.degrees(math.atan2(d["dy_m"], d["dx_m"]))}
    elif e.kind is Kind.POSE:
        values = {"x_m": p1.x_m, "y_m": p1.y_m, "z_m": p1.z_m,
                  "yaw_deg": math.degrees(p1.yaw_rad)}
    else:
        v = math.hypot(d["dx_m"], d["dy_m"]) / dt
        r = Range(e.get("min_m_s"), e.get("max_m_s"))
        return f"{v:.4f} m/s", f"speed {r} m/s", r.holds(v), p1.t_s, v
    measured, limit, ok, value = _ranges(e, values)
    return measured, limit, ok, p1.t_s, value


def _tactile(case: Case, e: Expectation, rec: Recording
             ) -> tuple[str, str, bool, float | None, float | None]:
    """H from the expectation, else the scenario's gait (the loader makes sure of one);
    l_i is the scenario's step length, else protocol/hexapod.py's."""
    gait = case.scenario.gait
    h_k = e.get("max_obstacle_height_m", gait.max_obstacle_height_m) \
        + steps_mod.OBSTACLE_CLEARANCE_M
    l_k = steps_mod.STEP_FACTOR * (gait.step_length_m or hexapod.STEP_LENGTH_M)
    h_tol, l_tol = e.get("h_tolerance_m"), e.get("l_tolerance_m")
    limit = f"h_k {h_k:.3f}±{h_tol:g} m, l_k {l_k:.3f}±{l_tol:g} m (Eq. 6-7)"
    joints = [(t, [j["position"] for j in m["joints"]]) for t, m in rec.on(topics.T_JOINTS)]
    times = [t for t, _ in joints]
    direction = math.radians(gait.direction_deg or 0.0)
    all_steps = [s for leg, track in enumerate(steps_mod.foot_tracks(joints))
                 for s in steps_mod.steps(times, track, leg, direction)]
    edges = [(t, m["leg"], bool(m["level"])) for t, m in rec.on(topics.T_SWITCHES)]
    t0, t1 = _window(e, rec)
    checked = steps_mod.steps_after_presses(all_steps, steps_mod.presses(edges, rec.end_s),
                                            e.get("min_press_s"), t0, t1)
    if len(checked) < e.get("min_steps"):
        return (f"{len(checked)} steps after a switch press", limit
                + f", at least {e.get('min_steps')} steps", False, None, None)
    bad = [s for s in checked if abs(s.height_m - h_k) > h_tol or abs(s.length_m - l_k) > l_tol]
    worst = bad[0] if bad else max(checked, key=lambda s: abs(s.height_m - h_k))
    leg = hexapod.LEGS[worst.leg]
    what = "first failing" if bad else "worst"
    measured = (f"h {worst.height_m:.3f} m, l {worst.length_m:.3f} m ({what}: {leg} step at "
                f"{worst.lift_off_s:.1f} s; {len(bad)} of {len(checked)} steps fail)")
    return measured, limit, not bad, worst.lift_off_s, worst.height_m


def _protocol(e: Expectation, rec: Recording) -> tuple[str, str, bool, float | None, float | None]:
    t0, t1 = _window(e, rec)
    allow = set(e.get("allow", []))
    bad = [(t, m["kind"]) for t, m in rec.on(topics.T_VIOLATIONS, t0, t1)
           if m["kind"] not in allow]
    kinds = sorted({k for _, k in bad})
    limit = "0 violations" + (f" (allowed: {', '.join(sorted(allow))})" if allow else "")
    measured = f"{len(bad)} violations" + (f" ({', '.join(kinds)})" if kinds else "")
    return measured, limit, not bad, bad[0][0] if bad else None, float(len(bad))


def _fault(e: Expectation, rec: Recording) -> tuple[str, str, bool, float | None, float | None]:
    t0, t1 = _window(e, rec)
    fault, within = e.get("fault"), e.get("within_s")
    faults = rec.on(topics.T_FAULTS, t0, t1)
    fired = [t for t, m in faults if m["name"] == fault]
    limit = f"{e.get('response').replace('_', ' ')} within {within:g} s of the first {fault}"
    if not fired:
        return f"no {fault} fault in the window", limit, False, None, None
    tf = fired[0]
    stops = [t for t, m in faults if m["name"] in ("safe_stop", "firmware_exception") and t >= tf]
    if e.get("response") == "safe_stop":
        if not stops:
            return f"no safe stop after {fault} at {tf:.2f} s", limit, False, tf + within, None
        dt = stops[0] - tf
        return f"stopped {dt:.2f} s after", limit, dt <= within, stops[0], dt
    until = min(tf + within, rec.end_s)
    early = [t for t in stops if t <= until]
    beats = [m["state"] for t, m in rec.on(topics.T_CAN_PREFIX + "heartbeat", tf, until)]
    walking = bool(beats) and all(s == WALKING for s in beats)
    if early or not walking:
        t = early[0] if early else until
        return (f"stopped {t - tf:.2f} s after" if early else "not walking after the fault",
                limit, False, t, t - tf)
    return f"walking {until - tf:.2f} s after", limit, True, until, until - tf


def _can(e: Expectation, rec: Recording) -> tuple[str, str, bool, float | None, float | None]:
    t0, t1 = _window(e, rec)
    name = e.get("message")
    frames = rec.on(topics.T_CAN_PREFIX + name, t0, t1)
    rate = len(frames) / max(t1 - t0, 1e-9)
    rate_r: Range = e.get("rate_hz", Range(low=1e-9))   # without one: a frame at least
    limits = [f"rate {rate_r} Hz" if e.get("rate_hz") else "1 frame or more"]
    limits += [f"{k} {r}" for k, r in e.get("signals", ())]
    measured = [f"{len(frames)} frames, {rate:.2f} Hz"]
    ok, fail_t = rate_r.holds(rate), None if rate_r.holds(rate) else t1
    for key, r in e.get("signals", ()):
        values = [(t, m.get(key)) for t, m in frames]
        if any(v is None for _, v in values):
            raise BadValue(f"{e.name}: CAN frame {name!r} has no signal {key!r}")
        if values:
            lo, hi = min(v for _, v in values), max(v for _, v in values)
            measured.append(f"{key} {lo:g}..{hi:g}")
            out = [t for t, v in values if not r.holds(v)]
            if out:
                ok, fail_t = False, out[0] if fail_t is None else min(fail_t, out[0])
    return "; ".join(measured), "; ".join(limits), ok, fail_t, rate


def _servo_limits(e: Expectation, rec: Recording
                  ) -> tuple[str, str, bool, float | None, float | None]:
    t0, t1 = _window(e, rec)
    ids = set(e.get("ids", []))
    measured, limits, ok, fail_t, value = [], [], True, None, None
    for key, r in e.ranges():
        series = [(t, s[key]) for t, m in rec.on(topics.T_SERVOS, t0, t1) for s in m["servos"]
                  if not ids or s["id"] in ids]
        if not series:
            return "no /servos samples", f"{key} {r}", False, None, None
        lo, hi = min(v for _, v in series), max(v for _, v in series)
        measured.append(f"{key} {lo:.3g}..{hi:.3g}")
        limits.append(f"{key} {r}")
        value = hi if value is None else value
        out = [t for t, v in series if not r.holds(v)]
        if out:
            ok = False
            fail_t = out[0] if fail_t is None else min(fail_t, out[0])
    return ", ".join(measured), ", ".join(limits), ok, fail_t, value


def _no_exception(e: Expectation, rec: Recording
                  ) -> tuple[str, str, bool, float | None, float | None]:
    if rec.summary.get("firmware_link") is False:   # a real board's trace (hexhil test --trace)
        return "not seen: no firmware link in this trace", "0 exceptions", False, None, None
    t0, t1 = _window(e, rec)
    raised = [t for t, m in rec.on(topics.T_FAULTS, t0, t1) if m["name"] == "firmware_exception"]
    n = max(len(raised), int(rec.summary.get("unhandled_exceptions", 0)))
    return f"{n} exceptions", "0 exceptions", n == 0, raised[0] if raised else None, float(n)


def _deadline(e: Expectation, rec: Recording
              ) -> tuple[str, str, bool, float | None, float | None]:
    """The busy time per control cycle of an ELF's run (the summary's ``deadline``)."""
    stat, most, late_ok = e.get("stat", "max"), e.get("max_busy_ms"), e.get("max_late")
    limit = f"busy {stat} <= {most:g} ms" + (f", <= {late_ok} late" if late_ok is not None
                                             else "")
    d = rec.summary.get("deadline")
    if not d:
        return ("not measured: no control cycles of an STM32F411 ELF (two servo bursts) in "
                "this run", limit, False, None, None)
    busy = d[f"busy_{stat}_ms"]
    ok = busy <= most and (late_ok is None or d["late"] <= late_ok)
    return (f"busy {stat} {busy:g} ms of a {d['period_ms']:g} ms period, {d['late']} late "
            f"of {d['cycles']}", limit, ok, None, busy)


def field_values(message: Any, path: str) -> list[float]:
    """The numbers at ``path`` in a decoded message: dotted keys, ``[i]`` an element,
    ``[*]`` every element (e.g. ``servos[*].temperature_c``); booleans count as 0/1."""
    items = [message]
    for part in path.replace("[", ".[").split("."):
        if not part:
            continue
        nxt = []
        for it in items:
            if part == "[*]" and isinstance(it, list):
                nxt.extend(it)
            elif part.startswith("[") and isinstance(it, list):
                i = int(part[1:-1])
                if -len(it) <= i < len(it):
                    nxt.append(it[i])
            elif isinstance(it, dict) and part in it:
                nxt.append(it[part])
        items = nxt
    out = []
    for v in items:
        if isinstance(v, (bool, int, float)):
            out.append(float(v))
    return out


def _signal(e: Expectation, rec: Recording) -> tuple[str, str, bool, float | None, float | None]:
    t0, t1 = _window(e, rec)
    topic, path, stat, r = e.get("topic"), e.get("field"), e.get("stat"), e.get("limit")
    series = [(t, v) for t, m in rec.on(topic, t0, t1) for v in field_values(m, path)]
    limit = f"{stat.value} {r}"
    if stat is Stat.COUNT:
        value, t = float(len(rec.on(topic, t0, t1))), t1
    elif not series:
        return f"no value at {topic} {path}", limit, False, None, None
    elif stat is Stat.MIN:
        t, value = min(series, key=lambda tv: tv[1])
    elif stat is Stat.MAX:
        t, value = max(series, key=lambda tv: tv[1])
    elif stat is Stat.MEAN:
        value, t = sum(v for _, v in series) / len(series), t1
    elif stat is Stat.AT:
        before = [tv for tv in series if tv[0] <= e.get("at_s")]
        if not before:
            return f"no value by {e.get('at_s'):g} s", limit, False, e.get("at_s"), None
        t, value = before[-1]
    else:
        changes = [series[i][0] for i in range(1, len(series)) if series[i][1] != series[i - 1][1]]
        value, t = float(len(changes)), changes[-1] if changes else t1
    return f"{value:.6g}", limit, r.holds(value), t, value


ENDING = "firmware ending"   # the outcome a firmware that did not complete its run adds


def ending_outcome(case: str, summary: dict[str, Any]) -> Outcome | None:
    """A firmware that crashed, hung, exited early or never started fails its case
    (``summary["ending"]``, hil/run_result.py ``FirmwareEnding``), at the moment it ended."""
    ending = summary.get("ending") or {}
    if ending.get("kind", "completed") == "completed":
        return None
    return Outcome(case, ENDING, ending["kind"], ending["reason"], "completed", False,
                   ending.get("t_s"))


def evaluate(case: Case, summary: dict[str, Any], trace: Path) -> list[Outcome]:
    """Every expectation of ``case`` on the run that produced ``summary`` and ``trace``,
    after the firmware's own ending when it did not complete the run."""
    return judged(case, read(trace, summary, topics_read(case)))


def judged(case: Case, rec: Recording) -> list[Outcome]:
    """``evaluate`` on a recording already read (or held in memory: the bus fuzzer's)."""
    summary = rec.summary
    kinds: dict[Kind, Callable[[Expectation, Recording], tuple]] = {
        Kind.DISPLACEMENT: _body, Kind.HEADING: _body, Kind.POSE: _body, Kind.SPEED: _body,
        Kind.PROTOCOL: _protocol, Kind.FAULT_RESPONSE: _fault, Kind.CAN: _can,
        Kind.SERVO_LIMITS: _servo_limits, Kind.NO_EXCEPTION: _no_exception,
        Kind.SIGNAL: _signal, Kind.DEADLINE: _deadline,
        Kind.TACTILE_RULE: lambda e, r: _tactile(case, e, r)}
    ended = ending_outcome(case.name, summary)
    out = [ended] if ended is not None else []
    for e in case.expectations:
        t0 = time.perf_counter()
        measured, limit, ok, t_s, value = kinds[e.kind](e, rec)
        out.append(Outcome(case.name, e.name, e.kind.value, measured, limit, ok, t_s, value,
                           time.perf_counter() - t0))
    return out
