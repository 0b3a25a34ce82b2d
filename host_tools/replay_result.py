"""What a replay into a firmware found (``hexhil replay``): whether the firmware said what
was logged and, where it did not, the first difference; shared by the replay of a recorded
run (host_tools/replay.py) and of a robot's log (host_tools/log_replay.py)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass
class Divergence:
    t_s: float
    topic: str
    expected: str
    actual: str
    exchange: int
    # on the servo line: each side's bytes in the diverging exchange as Dynamixel packets,
    # decoded in the protocol of the trace's servo model ("SYNC_WRITE to 254")
    packets: dict[str, list[str]] | None = None

    def as_dict(self) -> dict[str, Any]:
        return {"t_s": self.t_s, "topic": self.topic, "expected": self.expected,
                "actual": self.actual, "exchange": self.exchange, "packets": self.packets}


@dataclass
class ReplayResult:
    exchanges: int = 0
    compared_messages: int = 0
    identical: bool = True
    divergence: Divergence | None = None
    firmware_exit: int | None = None
    stderr_tail: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return {"identical": self.identical, "exchanges": self.exchanges,
                "compared_messages": self.compared_messages,
                "first_divergence": self.divergence.as_dict() if self.divergence else None,
                "firmware_exit": self.firmware_exit, **self.extra}
