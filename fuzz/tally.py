"""The figures one fuzz target reports, and the budget it runs under."""
from __future__ import annotations

import time
from dataclasses import dataclass, field


@dataclass
class Tally:
    """What one target did: inputs tried, exceptions that escaped, resyncs checked/found."""

    target: str
    unit: str
    inputs: int = 0
    escaped: int = 0
    resync_checked: int = 0
    resync_found: int = 0
    wall_s: float = 0.0
    first_escape: str = ""
    notes: dict[str, int] = field(default_factory=dict)

    def escape(self, what: str) -> None:
        """Count an exception that got out; keep the first for the report."""
        self.escaped += 1
        if not self.first_escape:
            self.first_escape = what

    @property
    def rate_per_s(self) -> float:
        return self.inputs / self.wall_s if self.wall_s > 0 else 0.0

    @property
    def resync_pct(self) -> float | None:
        if not self.resync_checked:
            return None
        return 100.0 * self.resync_found / self.resync_checked


class Budget:
    """Stop after ``limit`` inputs or ``budget_s`` of wall time, whichever comes first."""

    def __init__(self, budget_s: float | None, limit: int | None) -> None:
        self.t0 = time.perf_counter()
        self.deadline = None if budget_s is None else self.t0 + budget_s
        self.limit = limit

    def more(self, done: int) -> bool:
        if self.limit is not None and done >= self.limit:
            return False
        return self.deadline is None or done % 64 or time.perf_counter() < self.deadline

    def elapsed_s(self) -> float:
        return time.perf_counter() - self.t0
