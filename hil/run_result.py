"""What a lockstep run produced; ``host_tools/run.py`` turns it into the ``--json`` summary."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any


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
    no_servo_answered: str | None = None   # why, when the firmware wrote and none answered
    interrupted: bool = False   # Ctrl-C (or SIGTERM) ended it early

    @property
    def unhandled_exceptions(self) -> int:
        crashed = self.exit_code not in (0, None) and not self.exceptions
        return len(self.exceptions) + (1 if crashed else 0)

    def count_can(self, arb_id: int) -> None:
        key = "0x%03X" % arb_id
        self.can_frames[key] = self.can_frames.get(key, 0) + 1


class RunInterrupted(KeyboardInterrupt):
    """Ctrl-C (or SIGTERM) during a run: ``result`` is the run up to then (its trace is
    closed and kept); ``summary``, set by host_tools/run.py, its ``--json`` object."""

    def __init__(self, result: RunResult) -> None:
        super().__init__()
        self.result = result
        self.summary: dict[str, Any] = {}


def body_displacement(p0: Any, p1: Any) -> dict[str, float]:
    """From pose ``p0`` to ``p1`` in ``p0``'s heading frame: forward, left (m), turn (deg)."""
    c, s = math.cos(p0.yaw_rad), math.sin(p0.yaw_rad)
    dx, dy = p1.x_m - p0.x_m, p1.y_m - p0.y_m
    dyaw = math.degrees(math.atan2(math.sin(p1.yaw_rad - p0.yaw_rad),
                                   math.cos(p1.yaw_rad - p0.yaw_rad)))
    return {"dx_m": c * dx + s * dy, "dy_m": -s * dx + c * dy, "dyaw_deg": dyaw}
