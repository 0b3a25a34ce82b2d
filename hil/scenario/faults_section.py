"""The ``[faults]`` section as frozen types: the line's fault rates and the timed faults'
entries (a servo unplugged, stalled, overheating; a supply sag), every key, default and rule
here; hil/servobus/faults.py injects them."""
from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Any

from hil.scenario.rules import check_table, within
from protocol.errors import UserError


class FaultKind(str, Enum):
    UNPLUG = "unplug"
    STALL = "stall"
    OVERHEAT = "overheat"
    VOLTAGE_SAG = "voltage_sag"


_TIMED = {"at_s": (float, True), "until_s": (float, False)}
ENTRY_FIELDS: dict[FaultKind, dict[str, tuple[type, bool]]] = {
    FaultKind.UNPLUG: {"id": (int, True), **_TIMED},
    FaultKind.STALL: {"id": (int, True), **_TIMED},
    FaultKind.OVERHEAT: {"id": (int, True), **_TIMED, "temperature_c": (float, True)},
    FaultKind.VOLTAGE_SAG: {**_TIMED, "volts": (float, True), "ids": (list, False)},
}


@dataclass(frozen=True)
class FaultEntry:
    """One timed fault: from ``at_s`` (to ``until_s``, None: the run's end) on servo ``id``,
    or on ``ids`` (a sag; empty: every servo)."""

    kind: FaultKind
    at_s: float
    until_s: float | None = None
    id: int | None = None
    ids: tuple[int, ...] = ()
    temperature_c: float | None = None
    volts: float | None = None

    @classmethod
    def parse(cls, kind: FaultKind, raw: Any, where: str) -> "FaultEntry":
        if not isinstance(raw, dict):
            raise UserError(f"{where}: each '{kind.value}' entry must be a table like "
                            f"{{id = 3, at_s = 1.0}}, got {raw!r}")
        d = check_table(where, raw, ENTRY_FIELDS[kind], f"{kind.value}.",
                        f" in a '{kind.value}' entry")
        e = cls(kind, **{**d, "ids": tuple(d.get("ids", ()))})
        if e.at_s < 0 or (e.until_s is not None and e.until_s <= e.at_s):
            raise UserError(f"{where}: '{kind.value}' needs 0 <= at_s < until_s, got {raw!r}")
        for i in e.ids or (e.id if e.id is not None else 1,):
            if not isinstance(i, int) or isinstance(i, bool) or not 0 <= i <= 253:
                raise UserError(f"{where}: '{kind.value}' servo id must be 0-253, got {i!r}")
        return e


@dataclass(frozen=True)
class FaultsConfig:
    bit_error_rate: float = 0.0
    drop_status_rate: float = 0.0
    can_drop_rate: float = 0.0
    unplug: tuple[FaultEntry, ...] = ()
    stall: tuple[FaultEntry, ...] = ()
    overheat: tuple[FaultEntry, ...] = ()
    voltage_sag: tuple[FaultEntry, ...] = ()

    def entries(self) -> list[FaultEntry]:
        """Every timed fault, kind by kind in FaultKind's order, each kind as written."""
        return [*self.unplug, *self.stall, *self.overheat, *self.voltage_sag]

    def active(self) -> bool:
        """Whether the servo line has a fault to inject (the CAN drop rate is the CAN bus's)."""
        return bool(self.bit_error_rate or self.drop_status_rate or self.entries())

    @classmethod
    def parse(cls, where: str, d: dict[str, Any]) -> "FaultsConfig":
        entries = {k.value: tuple(FaultEntry.parse(k, e, f"{where} [faults]") for e in d[k.value])
                   for k in FaultKind if k.value in d}
        f = cls(**{**d, **entries})
        within(f"{where}: bit_error_rate", f.bit_error_rate, 0.0, 1.0, high_open=True)
        within(f"{where}: drop_status_rate", f.drop_status_rate, 0.0, 1.0)
        within(f"{where}: key 'faults.can_drop_rate'", f.can_drop_rate, 0.0, 1.0)
        return f
