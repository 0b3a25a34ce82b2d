"""How a conformance run reports, whatever protocol its checker speaks: one ``Check`` row per
servo and check, each failure blamed on what it may be (the servo's reply broke the spec, or
an expected reply never came), the JSON summary, and a table that shows a result shared by
several servos once, with their IDs."""
from __future__ import annotations

from dataclasses import asdict, dataclass
from enum import Enum
from typing import Any, Iterable

from hexhil.dynamixel.decode import words


class Cause(str, Enum):
    """What a failed check may be. A reply that breaks the spec is the servo's (it cannot come
    from a lost packet); a missing one, after every retry the spec allows, is a lost status
    packet or a servo that does not answer, and the checker cannot tell which."""

    NONE = ""               # passed or skipped
    SERVO = "servo"         # the servo answered against the spec: it does not conform
    NO_REPLY = "no reply"   # an expected reply never came: lost on the line, or never sent

    def explain(self) -> str:
        return {Cause.NONE: "",
                Cause.SERVO: "not conforming",
                Cause.NO_REPLY: "lost reply or silent servo"}[self]


@dataclass
class Check:
    id: int | None
    check: str
    result: str  # "pass", "fail" or "skip"
    detail: str
    cause: str = Cause.NONE.value


def summarise(port: str, baud: int, echo: bool, servos: list[int],
              rows: list[Check]) -> dict[str, Any]:
    """The JSON-ready result of a run (``ok`` true when rows exist and none failed)."""
    return {"port": port, "baud": baud, "echo": echo, "servos": servos,
            "ok": bool(rows) and all(r.result != "fail" for r in rows),
            "passed": sum(r.result == "pass" for r in rows),
            "failed": sum(r.result == "fail" for r in rows),
            "no_reply": sum(r.cause == Cause.NO_REPLY.value for r in rows),
            "skipped": sum(r.result == "skip" for r in rows),
            "checks": [asdict(r) for r in rows]}


def format_ids(ids: Iterable[int | None]) -> str:
    """``[1, 2, 3, 5]`` -> ``1-3,5``; ``None`` (a bus-wide row) -> ``-``."""
    nums = sorted({i for i in ids if i is not None})
    return words.ids(nums) if nums else "-"


def collapse(checks: list[dict[str, Any]]) -> list[tuple[list[int | None], dict[str, Any]]]:
    """Rows that differ only in their servo ID, as one (IDs, row) each: in the order the
    checks first ran, the lowest IDs first within a check."""
    groups: dict[tuple[str, str, str, str], list[int | None]] = {}
    first: dict[tuple[str, str, str, str], dict[str, Any]] = {}
    order = {c["check"]: n for n, c in reversed(list(enumerate(checks)))}
    for c in checks:
        key = (c["check"], c["result"], c.get("cause", ""), c["detail"])
        groups.setdefault(key, []).append(c["id"])
        first.setdefault(key, c)
    keys = sorted(groups, key=lambda k: (order[k[0]], min((i for i in groups[k] if i is not None),
                                                          default=-1)))
    return [(groups[k], first[k]) for k in keys]


def format_table(result: dict[str, Any]) -> str:
    """One line per distinct result; FAIL says whether the servo or the line may be at fault."""
    rows = [(format_ids(ids), r) for ids, r in collapse(result["checks"])]
    width = max([3] + [len(ids) for ids, _ in rows])
    lines = [f"{'ids':>{width}}  {'check':<26} {'result':<6} detail"]
    for ids, r in rows:
        why = Cause(r.get("cause", "")).explain()
        detail = f"[{why}] {r['detail']}" if why else r["detail"]
        lines.append(f"{ids:>{width}}  {r['check']:<26} {r['result'].upper():<6} {detail}")
    no_reply = result.get("no_reply", 0)
    lines.append(f"{result['passed']} passed, {result['failed']} failed"
                 + (f" ({no_reply} for want of a reply: run again, or check the wiring and "
                    f"baud)" if no_reply else "")
                 + f", {result['skipped']} skipped on {result['port']} at {result['baud']} bps"
                 + (" (echo detected and stripped)" if result["echo"] else ""))
    return "\n".join(lines)
