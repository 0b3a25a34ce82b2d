"""What a lockstep run produced; ``host_tools/run.py`` turns it into the ``--json`` summary."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum
from typing import Any

LAST_LINES = 5   # of what the firmware printed, kept with an ending that is not COMPLETED


class Ending(str, Enum):
    """How the firmware under test ended its run: anything but COMPLETED fails the run
    (a verdict on the firmware, not an error of hexhil)."""

    COMPLETED = "completed"              # served to the run's end (or stopped on its own)
    CRASHED = "crashed"                  # exited non-zero, or broke the link's rules
    HUNG = "hung"                        # no link message for a while, or only polls
    EXITED_EARLY = "exited_early"        # exited cleanly before the run's end
    FAILED_TO_START = "failed_to_start"  # never connected to the link


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


@dataclass
class RunResult:
    runtime: str
    sim_time_s: float = 0.0
    wall_time_s: float = 0.0
    cycles: int = 0
    overruns: int = 0
    exceptions: list[str] = field(default_factory=list)
    exit_code: int | None = None
    stderr_tail: str = ""
    serial_digest: str = ""
    faults: dict[str, int] = field(default_factory=dict)
    stop_reason: str | None = None
    firmware: dict[str, Any] = field(default_factory=dict)
    tactile_events: list[dict[str, Any]] = field(default_factory=list)
    switch_edges: int = 0
    can_frames: dict[str, int] = field(default_factory=dict)
    bus_busy_us: int = 0        # bus time of the loop's transactions (after the first cycle)
    bus_wire_us: int = 0        # wire minimum of the same bytes
    loop_cycles: int = 0        # cycles counted for the two figures above
    round_trips: int = 0
    body: dict[str, float] = field(default_factory=lambda: {"dx_m": 0.0, "dy_m": 0.0,
                                                            "dyaw_deg": 0.0})
    world: dict[str, Any] = field(default_factory=dict)   # a self-stepping world's outcome
    ending: FirmwareEnding = FirmwareEnding()

    @property
    def unhandled_exceptions(self) -> int:
        crashed = self.exit_code not in (0, None) and not self.exceptions
        return len(self.exceptions) + (1 if crashed else 0)

    def count_can(self, arb_id: int) -> None:
        key = "0x%03X" % arb_id
        self.can_frames[key] = self.can_frames.get(key, 0) + 1


def body_displacement(p0: Any, p1: Any) -> dict[str, float]:
    """From pose ``p0`` to ``p1`` in ``p0``'s heading frame: forward, left (m), turn (deg)."""
    c, s = math.cos(p0.yaw_rad), math.sin(p0.yaw_rad)
    dx, dy = p1.x_m - p0.x_m, p1.y_m - p0.y_m
    dyaw = math.degrees(math.atan2(math.sin(p1.yaw_rad - p0.yaw_rad),
                                   math.cos(p1.yaw_rad - p0.yaw_rad)))
    return {"dx_m": c * dx + s * dy, "dy_m": -s * dx + c * dy, "dyaw_deg": dyaw}
