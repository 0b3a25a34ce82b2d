"""Fault injection on the servo bus, from a scenario's ``[faults]`` (hil/scenario/faults_section.py:
its keys, defaults and rules; ``hexhil bus``'s flags write into it).

Line faults (bit errors, dropped status packets) draw from seeded RNGs, one stream each,
so a scenario and a seed give the same faults byte for byte. Timed faults (a servo
unplugged, stalled by an external load, overheating; supply voltage sag) fire at exact
virtual microseconds. Every injected fault, and every collision the bus sees, goes to
``on_fault(t_us, name, detail)`` and into ``counts`` for the run summary.
"""
from __future__ import annotations

import math
import random
from typing import Callable

from hil.scenario.faults_section import FaultEntry, FaultsConfig
from hil.servobus.health import SUPPLY_V

OnFault = Callable[[int, str, str], None]
NEVER_US = 1 << 62

class Faults:
    """Injected faults for one bus; ``Bus`` calls ``attach`` and the hooks below."""

    def __init__(self, config: FaultsConfig, seed: int = 0,
                 on_fault: OnFault | None = None) -> None:
        self.config = config
        self.bit_error_rate = config.bit_error_rate
        self.drop_status_rate = config.drop_status_rate
        self.on_fault = on_fault
        self.counts: dict[str, int] = {}
        self.log: list[tuple[int, str, str]] = []
        self._bits_rng = random.Random(f"{seed}:bits")
        self._drop_rng = random.Random(f"{seed}:drop")
        self._gap = self._draw_gap()
        self._events: list[tuple[int, int, bool, FaultEntry]] = []
        self.next_us = NEVER_US
        self.bus = None

    def active(self) -> bool:
        return self.config.active()

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
        for e in self.config.entries():
            events.append((t0 + int(round(e.at_s * 1e6)), seq, True, e))
            seq += 1
            if e.until_s is not None:
                events.append((t0 + int(round(e.until_s * 1e6)), seq, False, e))
                seq += 1
        events.sort(key=lambda ev: (ev[0], ev[1]))
        self._events = events
        self.next_us = events[0][0] if events else NEVER_US

    def apply_due(self, t_us: int) -> None:
        """Fire every timed fault due at or before t_us."""
        while self._events and self._events[0][0] <= t_us:
            te, _, start, e = self._events.pop(0)
            self._fire(te, start, e)
        self.next_us = self._events[0][0] if self._events else NEVER_US

    def _fire(self, t_us: int, start: bool, e: FaultEntry) -> None:
        bus = self.bus
        kind = e.kind.value
        ids = e.ids or ([e.id] if e.id is not None else [s.id for s in bus.servos])
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
                s.set_hot_spot(e.temperature_c if start else None, t_us)
                detail = (f"heating towards {e.temperature_c:g} C" if start
                          else "heat source removed")
            else:
                s.set_supply_v(e.volts if start else SUPPLY_V, t_us)
                detail = f"supply {e.volts:g} V" if start else f"supply back to {SUPPLY_V:g} V"
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
