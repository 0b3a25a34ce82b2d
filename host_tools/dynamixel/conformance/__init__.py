"""``hexhil conformance``'s checks, one module a protocol, keyed by its version: v1.py
(AX-12, Protocol 1.0), v2.py (X series, Protocol 2.0); report.py shapes either's rows."""
from __future__ import annotations

from typing import Any, Callable

from hexhil.dynamixel.conformance import v1, v2

RunChecks = Callable[[str, int, "list[int] | None", float, float], dict[str, Any]]
CHECKS: dict[int, RunChecks] = {1: v1.run_checks, 2: v2.run_checks}
