"""Fault injection on the servo bus, from a scenario's ``[faults]`` or ``hexhil bus`` flags.

Line faults (bit errors, dropped status packets) draw from seeded RNGs, one stream each,
so a scenario and a seed give the same faults byte for byte. Timed faults (a servo
unplugged, stalled by an external load, overheating; supply voltage sag) fire at exact
virtual microseconds. Every injected fault, and every collision the bus sees, goes to
``on_fault(t_us, name, detail)`` and into ``counts`` for the run summary.
"""
from __future__ import annotations

import math
import random
from typing import Any, Callable

from hil.servobus.health import SUPPLY_V
from protocol.errors import UserError

OnFault = Callable[[int, str, str], None]
NEVER_US = 1 << 62

# [faults] keys of each timed-fault entry: key -> (type, required)
_ENTRY_KEYS: dict[str, dict[str, tuple[type, bool]]] = {
    "unplug": {"id": (int, True), "at_s": (float, True), "until_s": (float, False)},
    "stall": {"id": (int, True), "at_s": (float, True), "until_s": (float, False)},
    "overheat": {"id": (int, True), "at_s": (float, True), "until_s": (float, False),
                 "temperature_c": (float, True)},
    "voltage_sag": {"at_s": (float, True), "until_s": (float, False), "volts": (float, True),
                    "ids": (list, False)},
}


def _entry(kind: str, raw: Any, where: str) -> dict[str, Any]:
    if not isinstance(raw, dict):
        raise UserError(f"{where}: each '{kind}' entry must be a table like "
                        f"{{id = 3, at_s = 1.0}}, got {raw!r}")
    keys = _ENTRY_KEYS[kind]
    out: dict[str, Any] = {}
    for k, v in raw.items():
        if k not in keys:
            raise UserError(f"{where}: unknown key '{k}' in a '{kind}' entry "
                            f"(known: {', '.join(sorted(keys))})")
        want = keys[k][0]
        if want is float and isinstance(v, int) and not isinstance(v, bool):
            v = float(v)
        if not isinstance(v, want) or isinstance(v, bool):
            raise UserError(f"{where}: '{kind}.{k}' must be {want.__name__}, got {v!r}")
        out[k] = v
    for k, (_, required) in keys.items():
        if required and k not in out:
            raise UserError(f"{where}: a '{kind}' entry needs '{k}'")
    if out["at_s"] < 0 or ("until_s" in out and out["until_s"] <= out["at_s"]):
        raise UserError(f"{where}: '{kind}' needs 0 <= at_s < until_s, got {raw!r}")
    for i in out.get("ids", [out.get("id", 1)]):
        if not isinstance(i, int) or not 0 <= i <= 253:
            raise UserError(f"{where}: '{kind}' servo id must be 0-253, got {i!r}")
    return out


def parse_flag(kind: str, spec: str) -> dict[str, Any]:
    """A ``hexhil bus`` fault flag as a [faults] entry.

    ``--unplug ID:AT_S[:UNTIL_S]``, ``--stall ID:AT_S[:UNTIL_S]``,
    ``--overheat ID:TEMP_C:AT_S[:UNTIL_S]``, ``--voltage-sag VOLTS:AT_S[:UNTIL_S]``.
    """
    parts = spec.split(":")
    head = 2 if kind in ("overheat",) else 1
    try:
        nums = [float(p) for p in parts]
    except ValueError:
        raise UserError(f"--{kind.replace('_', '-')} {spec!r}: expected numbers separated by ':'") from None
    if not head + 1 <= len(nums) <= head + 2:
        raise UserError(f"--{kind.replace('_', '-')} {spec!r}: see 'hexhil bus --help' for the form")
    out: dict[str, Any] = {"at_s": nums[head]}
    if len(nums) == head + 2:
        out["until_s"] = nums[head + 1]
    if kind == "voltage_sag":
        out["volts"] = nums[0]
    else:
        if nums[0] != int(nums[0]):
            raise UserError(f"--{kind} {spec!r}: servo id must be an integer")
        out["id"] = int(nums[0])
        if kind == "overheat":
            out["temperature_c"] = nums[1]
    return _entry(kind, out, f"--{kind.replace('_', '-')}")


class Faults:
    """Injected faults for one bus; ``Bus`` calls ``attach`` and the hooks below."""

    def __init__(self, seed: int = 0, bit_error_rate: float = 0.0, drop_status_rate: float = 0.0,
                 unplug: list | tuple = (), stall: list | tuple = (), overheat: list | tuple = (),
                 voltage_sag: list | tuple = (), on_fault: OnFault | None = None,
                 where: str = "faults") -> None:
        if not 0.0 <= bit_error_rate < 1.0:
            raise UserError(f"{where}: bit_error_rate must be in [0, 1), got {bit_error_rate}")
        if not 0.0 <= drop_status_rate <= 1.0:
            raise UserError(f"{where}: drop_status_rate must be in [0, 1], got {drop_status_rate}")
        self.bit_error_rate = bit_error_rate
        self.drop_status_rate = drop_status_rate
        self.on_fault = on_fault
        self.counts: dict[str, int] = {}
        self.log: list[tuple[int, str, str]] = []
        self._bits_rng = random.Random(f"{seed}:bits")
        self._drop_rng = random.Random(f"{seed}:drop")
        self._gap = self._draw_gap()
        self.entries = {
            "unplug": [_entry("unplug", e, where) for e in unplug],
            "stall": [_entry("stall", e, where) for e in stall],
            "overheat": [_entry("overheat", e, where) for e in overheat],
            "voltage_sag": [_entry("voltage_sag", e, where) for e in voltage_sag],
        }
        self._events: list[tuple[int, int, str, bool, dict[str, Any]]] = []
        self.next_us = NEVER_US
        self.bus = None

    @classmethod
    def from_scenario(cls, section: dict[str, Any], seed: int = 0, where: str = "faults",
                      on_fault: OnFault | None = None) -> "Faults":
        """From a loaded scenario's ``[faults]`` table (keys checked by hil.scenario)."""
        return cls(seed=seed, bit_error_rate=section.get("bit_error_rate", 0.0),
                   drop_status_rate=section.get("drop_status_rate", 0.0),
                   unplug=section.get("unplug", []), stall=section.get("stall", []),
                   overheat=section.get("overheat", []),
                   voltage_sag=section.get("voltage_sag", []), on_fault=on_fault, where=where)

    def active(self) -> bool:
        return bool(self.bit_error_rate or self.drop_status_rate
                    or any(self.entries.values()))

    # --- reporting ----------------------------------------------------------------
    def report(self, t_us: int, name: str, detail: str) -> None:
        self.counts[name] = self.counts.get(name, 0) + 1
        self.log.append((t_us, name, detail))
        if self.on_fault is not None:
            self.on_fault(t_us, name, detail)

    # --- timed faults -----------------------------------------------------------------
    def attach(self, bus) -> None:
        """Schedule the timed faults against ``bus`` (relative to its clock's now)."""
        self.bus = bus
        t0 = bus.clock.t_us
        seq = 0
        events = []
        for kind, entries in self.entries.items():
            for e in entries:
                events.append((t0 + int(round(e["at_s"] * 1e6)), seq, kind, True, e))
                seq += 1
                if "until_s" in e:
                    events.append((t0 + int(round(e["until_s"] * 1e6)), seq, kind, False, e))
                    seq += 1
        events.sort(key=lambda ev: (ev[0], ev[1]))
        self._events = events
        self.next_us = events[0][0] if events else NEVER_US

    def apply_due(self, t_us: int) -> None:
        """Fire every timed fault due at or before t_us."""
        while self._events and self._events[0][0] <= t_us:
            te, _, kind, start, e = self._events.pop(0)
            self._fire(te, kind, start, e)
        self.next_us = self._events[0][0] if self._events else NEVER_US

    def _fire(self, t_us: int, kind: str, start: bool, e: dict[str, Any]) -> None:
        bus = self.bus
        ids = e.get("ids") or ([e["id"]] if "id" in e else [s.id for s in bus.servos])
        for dev_id in ids:
            s = bus.servo(dev_id)
            if s is None:
                self.report(t_us, kind, f"id {dev_id}: no such servo, nothing injected")
                continue
            if kind == "unplug":
                bus.set_plugged(s, not start, t_us)
                detail = "unplugged" if start else "plugged back (power-cycled)"
            elif kind == "stall":
                s.set_stalled(start, t_us)
                detail = "stalled by an external load" if start else "load removed"
            elif kind == "overheat":
                s.set_hot_spot(e["temperature_c"] if start else None, t_us)
                detail = (f"heating towards {e['temperature_c']:g} C" if start
                          else "heat source removed")
            else:
                s.set_supply_v(e["volts"] if start else SUPPLY_V, t_us)
                detail = f"supply {e['volts']:g} V" if start else f"supply back to {SUPPLY_V:g} V"
            self.report(t_us, kind if start else kind + "_end", f"id {dev_id}: {detail}")

    # --- line faults ---------------------------------------------------------------
    def _draw_gap(self) -> int:
        """Error-free data bits before the next flipped one (geometric)."""
        p = self.bit_error_rate
        if p <= 0.0:
            return NEVER_US
        u = 1.0 - self._bits_rng.random()  # (0, 1]
        return int(math.log(u) / math.log1p(-p))

    def corrupt(self, data: bytearray, t_us: int, direction: str) -> int:
        """Flip data bits at the bit error rate; return how many flipped."""
        nbits = 8 * len(data)
        pos = self._gap
        if pos >= nbits:
            self._gap = pos - nbits
            return 0
        flips = 0
        while pos < nbits:
            data[pos >> 3] ^= 1 << (pos & 7)
            flips += 1
            self.report(t_us, "bit_error", f"{direction} byte {pos >> 3} bit {pos & 7}")
            pos += 1 + self._draw_gap()
        self._gap = pos - nbits
        return flips

    def drop_status(self, dev_id: int, t_us: int) -> bool:
        """Whether this status packet is lost (drawn per reply)."""
        if self.drop_status_rate and self._drop_rng.random() < self.drop_status_rate:
            self.report(t_us, "drop_status", f"id {dev_id}: status packet lost")
            return True
        return False
