"""What a lockstep run produced. During the run the link's host side and the drivers add into
a ``RunTally`` (hil/link/server.py, hil/run/lockstep.py); when it ends, ``RunTally.result()``
freezes it into the public ``RunResult`` (host_tools/run_summary.py turns that into the ``--json``
summary). Below hil/link/ and hil/run/, so no arrow runs back up."""
from __future__ import annotations

import math
from dataclasses import MISSING, dataclass, field, fields
from enum import Enum
from types import MappingProxyType
from typing import Any, Mapping

from hexhil.protocol import link_schema as ls

LAST_LINES = 5   # of what the firmware printed, kept with an ending that is not COMPLETED
CONSOLE_LINES = 20   # the console's last lines (virtual time, text) a run result keeps


class Ending(str, Enum):
    """How the firmware under test ended its run: anything but COMPLETED fails the run
    (a verdict on the firmware, not an error of hexhil)."""

    COMPLETED = "completed"              # served to the run's end (or stopped on its own)
    CRASHED = "crashed"                  # exited non-zero, or broke the link's rules
    HUNG = "hung"                        # no link message for a while, or only polls
    EXITED_EARLY = "exited_early"        # exited cleanly before the run's end
    FAILED_TO_START = "failed_to_start"  # never connected to the link
    LIMIT = "limit"                      # ended by the run's wall-clock or memory cap


@dataclass(frozen=True)
class FirmwareEnding:
    """``kind`` with its one-line ``reason``, the firmware's last lines (stderr, else
    stdout), the virtual time it ended at and its exit status (None: still running)."""

    kind: Ending = Ending.COMPLETED
    reason: str = ""
    last_lines: tuple[str, ...] = ()
    t_s: float | None = None
    exit_code: int | None = None

    @property
    def completed(self) -> bool:
        return self.kind is Ending.COMPLETED

    def as_dict(self) -> dict[str, Any]:
        return {"kind": self.kind.value, "reason": self.reason,
                "last_lines": list(self.last_lines),
                "t_s": None if self.t_s is None else round(self.t_s, 6),
                "exit_code": self.exit_code}


def _frozen(d: Mapping[str, Any]) -> Mapping[str, Any]:
    return MappingProxyType(dict(d))


@dataclass(frozen=True)
class BodyDisplacement:
    """From the start pose to the end pose, in the start heading's frame."""

    dx_m: float = 0.0        # forward
    dy_m: float = 0.0        # left
    dyaw_deg: float = 0.0    # turn, counter-clockwise

    @classmethod
    def between(cls, p0: Any, p1: Any) -> "BodyDisplacement":
        """From pose ``p0`` to ``p1`` (hil/seams.py ``Pose``)."""
        c, s = math.cos(p0.yaw_rad), math.sin(p0.yaw_rad)
        dx, dy = p1.x_m - p0.x_m, p1.y_m - p0.y_m
        dyaw = math.degrees(math.atan2(math.sin(p1.yaw_rad - p0.yaw_rad),
                                       math.cos(p1.yaw_rad - p0.yaw_rad)))
        return cls(c * dx + s * dy, -s * dx + c * dy, dyaw)

    def as_dict(self) -> dict[str, float]:
        return {"dx_m": self.dx_m, "dy_m": self.dy_m, "dyaw_deg": self.dyaw_deg}


@dataclass(frozen=True)
class FirmwareStats:
    """The firmware's last stats event (protocol/link_schema.py STATS; defaults: not sent).
    ``other`` keeps the keys that schema does not name (a user's own firmware's)."""

    state: str | None = None
    stop_reason: str | None = None
    gait: str | None = None
    period_s: float | None = None
    cycles: int = 0
    overruns: int = 0
    found: int | None = None
    boot_s: float = 0.0
    echo: bool | None = None
    transactions: int = 0
    sync_writes: int = 0
    timeouts: int = 0
    corrupt_replies: int = 0
    error_statuses: int = 0
    echo_mismatch: int = 0
    servos: Mapping[str, Any] = field(default_factory=lambda: _frozen({}))
    ik_clamped: int = 0
    switch_edges: int = 0
    trajectory_changes: int = 0
    steps: int = 0
    commanded_distance_m: float = 0.0
    commands: int = 0
    compute_us_mean: float | None = None
    compute_us_max: int | None = None
    other: Mapping[str, Any] = field(default_factory=lambda: _frozen({}))

    @classmethod
    def from_event(cls, obj: Mapping[str, Any]) -> "FirmwareStats":
        """From the event's JSON object (its keys as the firmware sent them)."""
        known = {f.name for f in fields(cls)} - {"other"}
        kw = {k: v for k, v in obj.items() if k in known}
        if ls.SERVO_ERRORS in kw:
            kw[ls.SERVO_ERRORS] = _frozen(kw[ls.SERVO_ERRORS])
        return cls(**kw, other=_frozen({k: v for k, v in obj.items() if k not in known}))


@dataclass(frozen=True)
class BeamsOutcome:
    """How seed 000's traversal of the two beams ended (hil/world/beams_node.py)."""

    traversed: bool
    flipped: bool
    stuck: bool
    energy_J: float
    k0: float
    t_contact_s: float | None
    t_end_s: float
    x_end_m: float
    max_roll_deg: float
    max_pitch_deg: float

    def as_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass(frozen=True)
class HexapodOutcome:
    """A firmware-driven world's state at the run's end: the body's pose in the world
    frame and the feet that carry load (None where the world does not say)."""

    x_m: float
    y_m: float
    z_m: float
    yaw_deg: float
    feet_on_ground: int | None = None

    def as_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass(frozen=True)
class RunResult:
    runtime: str
    sim_time_s: float = 0.0
    wall_time_s: float = 0.0
    cycles: int = 0
    overruns: int = 0
    exceptions: tuple[str, ...] = ()
    exit_code: int | None = None
    stderr_tail: str = ""
    serial_digest: str = ""
    faults: Mapping[str, int] = field(default_factory=lambda: _frozen({}))
    stop_reason: str | None = None
    firmware: FirmwareStats = FirmwareStats()
    tactile_events: tuple[Mapping[str, Any], ...] = ()
    switch_edges: int = 0
    can_frames: Mapping[int, int] = field(default_factory=lambda: _frozen({}))  # by arbitration id
    bus_busy_us: int = 0        # bus time of the loop's transactions (after the first cycle)
    bus_wire_us: int = 0        # wire minimum of the same bytes
    loop_cycles: int = 0        # cycles counted for the two figures above
    round_trips: int = 0
    body: BodyDisplacement = BodyDisplacement()
    # A self-stepping world's outcome (beams), or a firmware-driven one's state at the end
    # (the hexapod); None without a world.
    world: BeamsOutcome | HexapodOutcome | None = None
    # What the run's host nodes report at its end (seed 000's traversal: strategy, estimate,
    # plan; the papers' packages fill it), as they report it.
    host_nodes: Mapping[str, Any] = field(default_factory=lambda: _frozen({}))
    ending: FirmwareEnding = FirmwareEnding()   # how the firmware ended (COMPLETED: served on)
    no_servo_answered: str | None = None   # why, when the firmware wrote and none answered
    interrupted: bool = False   # Ctrl-C (or SIGTERM) ended it early
    limit_hit: str | None = None   # "wall" or "memory": the cap that ended it (hil/run/limits.py)
    console_dropped_bytes: int = 0   # of the firmware's prints, past what the trace keeps
    # the bus master's protocol mistakes (hil/servobus/master_check.py ``summary``), where
    # the run checked them (a firmware of yours, every hexhil test case); else None
    violations: Mapping[str, Any] | None = None
    console: tuple[tuple[float, str], ...] = ()   # the firmware's last log lines (t_s, text)

    @property
    def unhandled_exceptions(self) -> int:
        crashed = self.exit_code not in (0, None) and not self.exceptions
        return len(self.exceptions) + (1 if crashed else 0)


# RunResult's fields a run adds into as it goes, as the mutable form the tally holds;
# ``firmware`` is the last stats event as sent, typed (``FirmwareStats``) when frozen.
_GROWING: dict[str, Any] = {"exceptions": list, "faults": dict, "tactile_events": list,
                            "can_frames": dict, "firmware": dict, "console": list}
# RunResult's fields that are not counted during the run: the firmware's stats give cycles
# and overruns; the papers' host nodes report theirs after it (host_nodes).
_AFTER = ("cycles", "overruns", "host_nodes")


class RunTally:
    """A run's figures while it runs: ``RunResult``'s own fields (declared once, there),
    mutable, but for those in ``_AFTER``; ``result()`` freezes them."""

    def __init__(self, runtime: str) -> None:
        self.runtime = runtime
        for f in fields(RunResult):
            if f.name in _AFTER or f.name == "runtime":
                continue
            if f.name in _GROWING:
                setattr(self, f.name, _GROWING[f.name]())
            elif f.default is not MISSING:
                setattr(self, f.name, f.default)
            else:
                setattr(self, f.name, f.default_factory())   # type: ignore[misc]

    def console_line(self, t_s: float, text: str) -> None:
        """A line the firmware printed (a log event), the last ``CONSOLE_LINES`` kept."""
        self.console.append((t_s, text))
        if len(self.console) > 2 * CONSOLE_LINES:
            del self.console[:-CONSOLE_LINES]

    def count_can(self, arb_id: int) -> None:
        self.can_frames[arb_id] = self.can_frames.get(arb_id, 0) + 1

    def count_fault(self, name: str) -> None:
        self.faults[name] = self.faults.get(name, 0) + 1

    def result(self) -> RunResult:
        """The frozen result; cycles, overruns and the stop reason from the firmware's stats."""
        stats = FirmwareStats.from_event(self.firmware)
        values = {f.name: getattr(self, f.name) for f in fields(RunResult)
                  if f.name not in _AFTER}
        values.update(
            exceptions=tuple(self.exceptions), faults=_frozen(self.faults), firmware=stats,
            tactile_events=tuple(_frozen(e) for e in self.tactile_events),
            can_frames=_frozen(self.can_frames), cycles=int(stats.cycles),
            overruns=int(stats.overruns), console=tuple(self.console[-CONSOLE_LINES:]),
            stop_reason=self.stop_reason if self.stop_reason is not None else stats.stop_reason)
        return RunResult(**values)


class RunInterrupted(KeyboardInterrupt):
    """Ctrl-C (or SIGTERM) during a run: ``result`` is the run up to then (its trace is
    closed and kept); ``summary``, set by host_tools/run_summary.py, its ``--json`` object."""

    def __init__(self, result: RunResult) -> None:
        super().__init__()
        self.result = result
        self.summary: dict[str, Any] = {}
