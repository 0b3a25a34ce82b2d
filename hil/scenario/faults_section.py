"""The ``[faults]`` section as frozen types: the line's fault rates and the timed faults'
entries (a servo unplugged, stalled, overheating; a supply sag; and the named failures:
brown-out, overload, a stuck or noisy position, two servos on one ID, a stuck or bouncing
switch, the CAN sensor node silent or babbling, seed 000's force sensor biased or dropping
out), every key, default and rule here; hil/servobus/faults.py injects them."""
from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Any, Sequence

from hexhil.hil.scenario.rules import check_table, within
from hexhil.protocol.hexapod import LEGS
from hexhil.protocol.errors import BadValue


class FaultKind(str, Enum):
    UNPLUG = "unplug"
    STALL = "stall"
    OVERHEAT = "overheat"
    VOLTAGE_SAG = "voltage_sag"
    BROWNOUT = "brownout"
    OVERLOAD = "overload"
    POSITION_STUCK = "position_stuck"
    POSITION_NOISE = "position_noise"
    ID_CONFLICT = "id_conflict"
    SWITCH_STUCK = "switch_stuck"
    SWITCH_BOUNCE = "switch_bounce"
    SWITCH_SWING_PRESS = "switch_swing_press"
    CAN_SILENT = "can_silent"
    CAN_GARBAGE = "can_garbage"
    FORCE_BIAS = "force_bias"
    FORCE_DROPOUT = "force_dropout"
    # one servo's status packets mangled on the line while the fault lasts
    STATUS_CHECKSUM = "status_checksum"
    STATUS_WRONG_ID = "status_wrong_id"
    STATUS_TRUNCATED = "status_truncated"
    STATUS_PADDED = "status_padded"
    STATUS_ERROR = "status_error"
    STATUS_LATE = "status_late"
    STATUS_MISSING = "status_missing"
    STATUS_TWIN = "status_twin"
    # the run's CAN bus, both ways, while the fault lasts
    CAN_DROPPED = "can_dropped"
    CAN_DELAYED = "can_delayed"
    CAN_REORDERED = "can_reordered"
    CAN_CORRUPT = "can_corrupt"


SWITCH_KINDS = (FaultKind.SWITCH_STUCK, FaultKind.SWITCH_BOUNCE)   # one a leg at a time
CAN_KINDS = (FaultKind.CAN_SILENT, FaultKind.CAN_GARBAGE)
FORCE_KINDS = (FaultKind.FORCE_BIAS, FaultKind.FORCE_DROPOUT)  # hil/world/beams_node.py
STATUS_KINDS = (FaultKind.STATUS_CHECKSUM, FaultKind.STATUS_WRONG_ID, FaultKind.STATUS_TRUNCATED,
                FaultKind.STATUS_PADDED, FaultKind.STATUS_ERROR, FaultKind.STATUS_LATE,
                FaultKind.STATUS_MISSING, FaultKind.STATUS_TWIN)
BUS_CAN_KINDS = (FaultKind.CAN_DROPPED, FaultKind.CAN_DELAYED, FaultKind.CAN_REORDERED,
                 FaultKind.CAN_CORRUPT)   # hil/canbus/bus.py
SERVO_STATE_KINDS = (FaultKind.BROWNOUT, FaultKind.OVERLOAD, FaultKind.POSITION_STUCK,
                     FaultKind.POSITION_NOISE, FaultKind.ID_CONFLICT)

_AT = {"at_s": (float, True)}
_TIMED = {**_AT, "until_s": (float, False)}
_ID = {"id": (int, True)}
ENTRY_FIELDS: dict[FaultKind, dict[str, tuple[type, bool]]] = {
    FaultKind.UNPLUG: {**_ID, **_TIMED},
    FaultKind.STALL: {**_ID, **_TIMED},
    FaultKind.OVERHEAT: {**_ID, **_TIMED, "temperature_c": (float, True)},
    FaultKind.VOLTAGE_SAG: {**_TIMED, "volts": (float, True), "ids": (list, False)},
    FaultKind.BROWNOUT: {**_ID, **_AT},
    FaultKind.OVERLOAD: {**_ID, **_AT},
    FaultKind.POSITION_STUCK: {**_ID, **_TIMED},
    FaultKind.POSITION_NOISE: {**_ID, **_TIMED, "sigma": (float, True)},
    FaultKind.ID_CONFLICT: {**_ID, "as_id": (int, True), **_TIMED},
    FaultKind.SWITCH_STUCK: {"leg": (int, True), "pressed": (bool, True), **_TIMED},
    FaultKind.SWITCH_BOUNCE: {"leg": (int, True), "period_s": (float, True), **_TIMED},
    FaultKind.SWITCH_SWING_PRESS: {"leg": (int, True), "after_s": (float, False),
                                   "press_s": (float, False), **_TIMED},
    FaultKind.CAN_SILENT: dict(_TIMED),
    FaultKind.CAN_GARBAGE: dict(_TIMED),
    FaultKind.FORCE_BIAS: {**_TIMED, "fx_n": (float, True), "fz_n": (float, False)},
    FaultKind.FORCE_DROPOUT: dict(_TIMED),
    FaultKind.STATUS_CHECKSUM: {**_ID, **_TIMED},
    FaultKind.STATUS_WRONG_ID: {**_ID, "as_id": (int, True), **_TIMED},
    FaultKind.STATUS_TRUNCATED: {**_ID, **_TIMED},
    FaultKind.STATUS_PADDED: {**_ID, **_TIMED},
    FaultKind.STATUS_ERROR: {**_ID, "bits": (int, True), **_TIMED},
    FaultKind.STATUS_LATE: {**_ID, "delay_s": (float, True), **_TIMED},
    FaultKind.STATUS_MISSING: {**_ID, **_TIMED},
    FaultKind.STATUS_TWIN: {**_ID, **_TIMED},
    FaultKind.CAN_DROPPED: dict(_TIMED),
    FaultKind.CAN_DELAYED: {**_TIMED, "delay_s": (float, True)},
    FaultKind.CAN_REORDERED: dict(_TIMED),
    FaultKind.CAN_CORRUPT: dict(_TIMED),
}


@dataclass(frozen=True)
class FaultEntry:
    """One timed fault: from ``at_s`` (to ``until_s``, None: the run's end) on servo ``id``,
    on ``ids`` (a sag; empty: every servo), on leg ``leg`` (a switch) or on the run's CAN
    node or force sensor."""

    kind: FaultKind
    at_s: float
    until_s: float | None = None
    id: int | None = None
    ids: tuple[int, ...] = ()
    temperature_c: float | None = None
    volts: float | None = None
    sigma: float | None = None          # position_noise, in position units
    as_id: int | None = None            # id_conflict: the ID servo ``id`` answers too
    leg: int | None = None              # switch faults: 0-5 = LF LM LH RF RM RH
    pressed: bool | None = None         # switch_stuck
    period_s: float | None = None       # switch_bounce: the chatter period
    fx_n: float | None = None           # force_bias
    fz_n: float | None = None
    bits: int | None = None             # status_error: the error byte's bits set (1-255)
    delay_s: float | None = None        # status_late, can_delayed: how much later
    after_s: float = 0.1                # switch_swing_press: the foot this long in the air,
    press_s: float = 0.03               # ... then the switch pressed this long

    @classmethod
    def parse(cls, kind: FaultKind, raw: Any, where: str) -> "FaultEntry":
        if not isinstance(raw, dict):
            raise BadValue(f"{where}: each '{kind.value}' entry must be a table like "
                           f"{{id = 3, at_s = 1.0}}, got {raw!r}")
        if isinstance(raw.get("leg"), str):   # a leg by its name, as the docs name them
            name = raw["leg"].upper()
            if name not in LEGS:
                raise BadValue(f"{where}: '{kind.value}.leg' must be 0-5 or one of "
                               f"{', '.join(LEGS)}, got {raw['leg']!r}")
            raw = {**raw, "leg": LEGS.index(name)}
        d = check_table(where, raw, ENTRY_FIELDS[kind], f"{kind.value}.",
                        f" in a '{kind.value}' entry")
        e = cls(kind, **{**d, "ids": tuple(d.get("ids", ()))})
        if e.at_s < 0 or (e.until_s is not None and e.until_s <= e.at_s):
            raise BadValue(f"{where}: '{kind.value}' needs 0 <= at_s < until_s, got {raw!r}")
        ids = [*(e.ids or (e.id if e.id is not None else 1,)),
               *((e.as_id,) if e.as_id is not None else ())]
        for i in ids:
            if not isinstance(i, int) or isinstance(i, bool) or not 0 <= i <= 253:
                raise BadValue(f"{where}: '{kind.value}' servo id must be 0-253, got {i!r}")
        if e.leg is not None and not 0 <= e.leg <= 5:
            raise BadValue(f"{where}: '{kind.value}.leg' must be 0-5 (LF, LM, LH, RF, RM, RH),"
                           f" got {e.leg}")
        if (e.sigma is not None and e.sigma < 0) or (e.period_s is not None and e.period_s <= 0):
            raise BadValue(f"{where}: '{kind.value}' needs sigma >= 0 and period_s > 0, "
                           f"got {raw!r}")
        if e.after_s < 0 or e.press_s <= 0:
            raise BadValue(f"{where}: '{kind.value}' needs after_s >= 0 and press_s > 0, "
                           f"got {raw!r}")
        if e.bits is not None and not 1 <= e.bits <= 255:
            raise BadValue(f"{where}: '{kind.value}.bits' must be 1-255 (the AX-12's seven "
                           f"error bits; Protocol 2.0's error number 1-7 and alert bit "
                           f"128), got {e.bits}")
        if e.delay_s is not None and not 0 < e.delay_s <= 1.0:
            raise BadValue(f"{where}: '{kind.value}.delay_s' must be in (0, 1] s, got "
                           f"{e.delay_s:g}")
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
    brownout: tuple[FaultEntry, ...] = ()
    overload: tuple[FaultEntry, ...] = ()
    position_stuck: tuple[FaultEntry, ...] = ()
    position_noise: tuple[FaultEntry, ...] = ()
    id_conflict: tuple[FaultEntry, ...] = ()
    switch_stuck: tuple[FaultEntry, ...] = ()
    switch_bounce: tuple[FaultEntry, ...] = ()
    switch_swing_press: tuple[FaultEntry, ...] = ()
    can_silent: tuple[FaultEntry, ...] = ()
    can_garbage: tuple[FaultEntry, ...] = ()
    force_bias: tuple[FaultEntry, ...] = ()
    force_dropout: tuple[FaultEntry, ...] = ()
    status_checksum: tuple[FaultEntry, ...] = ()
    status_wrong_id: tuple[FaultEntry, ...] = ()
    status_truncated: tuple[FaultEntry, ...] = ()
    status_padded: tuple[FaultEntry, ...] = ()
    status_error: tuple[FaultEntry, ...] = ()
    status_late: tuple[FaultEntry, ...] = ()
    status_missing: tuple[FaultEntry, ...] = ()
    status_twin: tuple[FaultEntry, ...] = ()
    can_dropped: tuple[FaultEntry, ...] = ()
    can_delayed: tuple[FaultEntry, ...] = ()
    can_reordered: tuple[FaultEntry, ...] = ()
    can_corrupt: tuple[FaultEntry, ...] = ()

    def entries(self) -> list[FaultEntry]:
        """Every timed fault, kind by kind in FaultKind's order, each kind as written."""
        return [e for k in FaultKind for e in getattr(self, k.value)]

    def active(self) -> bool:
        """Whether the servo line has a fault to inject (the CAN drop rate is the CAN bus's)."""
        return bool(self.bit_error_rate or self.drop_status_rate or self.entries())

    def check_ids(self, where: str, ids: Sequence[int]) -> None:
        """Every servo a fault names (``id``, a sag's ``ids``) is one of the bus's ``ids``:
        a fault on a servo that is not there would never happen."""
        have = set(ids)
        for e in self.entries():
            for i in (*e.ids, *((e.id,) if e.id is not None else ())):
                if i not in have:
                    lo, hi = min(have), max(have)
                    raise BadValue(f"{where}: '{e.kind.value}' names servo {i}, and the bus "
                                    f"has IDs {lo}-{hi}" if len(have) == hi - lo + 1 else
                                    f"{where}: '{e.kind.value}' names servo {i}, not on the bus")

    @classmethod
    def parse(cls, where: str, d: dict[str, Any]) -> "FaultsConfig":
        entries = {k.value: tuple(FaultEntry.parse(k, e, f"{where} [faults]") for e in d[k.value])
                   for k in FaultKind if k.value in d}
        f = cls(**{**d, **entries})
        within(f"{where}: bit_error_rate", f.bit_error_rate, 0.0, 1.0, high_open=True)
        within(f"{where}: drop_status_rate", f.drop_status_rate, 0.0, 1.0)
        within(f"{where}: key 'faults.can_drop_rate'", f.can_drop_rate, 0.0, 1.0)
        return f
