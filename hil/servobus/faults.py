"""Fault injection on the servo bus, from a scenario's ``[faults]`` (hil/scenario/faults_section.py:
its keys, defaults and rules; ``hexhil bus``'s flags write into it).

Line faults (bit errors, dropped status packets) draw from seeded RNGs, one stream each,
so a scenario and a seed give the same faults byte for byte. Timed faults fire at exact
virtual microseconds: a servo unplugged, stalled by an external load, overheating; supply
voltage sag; and the named failures (docs/servo-bus.md "Fault vocabulary"): a
servo's brown-out (it reboots), its Present Position stuck or noisy (seeded), an overload
(the Overload bit, torque off per Alarm Shutdown), two servos answering one ID, a leg's
limit switch stuck or bouncing, the CAN sensor node silent or sending garbage, seed 000's
force sensor biased or dropping out. ``inject`` adds one at run time. Every injected fault, and
every collision the bus sees, goes to ``on_fault(t_us, name, detail)`` and into ``counts``
for the run summary.
"""
from __future__ import annotations

import math
import random
from typing import Any, Callable, Sequence

from hexhil.hil.scenario.faults_section import (BUS_CAN_KINDS, CAN_KINDS, FORCE_KINDS,
                                         SERVO_STATE_KINDS, STATUS_KINDS, SWITCH_KINDS,
                                         FaultEntry, FaultKind, FaultsConfig)
from hexhil.hil.servobus.health import SUPPLY_V
from hexhil.hil.servobus.fault_effects import NoisyReading, StuckReading, SwingPress
from hexhil.hil.servobus.status_mangling import mangled
from hexhil.protocol.errors import BadValue, UserError

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
        self.entries: list[FaultEntry] = config.entries()   # and those injected at run time
        self._seed = seed
        self._events: list[tuple[int, int, bool, FaultEntry]] = []
        self._seq = 0
        self._t0_us = 0
        self._clock: Any = None                                     # set by start
        self._switches: dict[int, tuple[FaultEntry, int]] = {}     # leg -> (entry, since)
        self._swings: dict[int, SwingPress] = {}                    # leg -> its swing press
        self._conflicts: dict[int, Any] = {}                        # id(entry) -> servo
        self._can_node: FaultKind | None = None                     # a CAN_KINDS, or None
        self._garbage_rng = random.Random(f"{seed}:can_garbage")
        self._force_bias: tuple[float, float] | None = None         # (fx_n, fz_n) added
        self._force_dropout = False
        self._status: dict[int, list[FaultEntry]] = {}             # id -> its status faults
        self.can_faults: list[FaultEntry] = []                      # hil/canbus/bus.py reads
        self._can_rng = random.Random(f"{seed}:can_corrupt")
        self.next_us = NEVER_US
        self.bus = None

    def active(self) -> bool:
        return bool(self.bit_error_rate or self.drop_status_rate or self.entries)

    # --- reporting ----------------------------------------------------------------
    def report(self, t_us: int, name: str, detail: str) -> None:
        self.counts[name] = self.counts.get(name, 0) + 1
        self.log.append((t_us, name, detail))
        if self.on_fault is not None:
            self.on_fault(t_us, name, detail)

    # --- timed faults -----------------------------------------------------------------
    def attach(self, bus, t0_us: int | None = None) -> None:
        """Schedule the timed faults against ``bus``, relative to ``t0_us`` (default: its
        clock's now)."""
        self.bus = bus
        self.start(bus.clock, t0_us)

    def start(self, clock: Any, t0_us: int | None = None) -> None:
        """Schedule the timed faults from ``t0_us`` (default: ``clock``'s now); whoever
        moves the clock calls ``apply_due`` (the bus, or a self-stepping world's driver:
        hil/run/lockstep.py)."""
        self._clock = clock
        self._t0_us = clock.t_us if t0_us is None else t0_us
        for e in self.entries:
            self._schedule(e)

    def _schedule(self, e: FaultEntry) -> None:
        for start, t_s in ((True, e.at_s), (False, e.until_s)):
            if t_s is not None:
                self._events.append((self._t0_us + int(round(t_s * 1e6)), self._seq, start, e))
                self._seq += 1
        self._events.sort(key=lambda ev: (ev[0], ev[1]))
        self.next_us = self._events[0][0] if self._events else NEVER_US

    def inject(self, kind: str, **params: Any) -> FaultEntry:
        """A timed fault at run time (the API, a host node, ``hexhil bus``): ``at_s`` (run
        time, default now) and ``until_s`` as in ``[faults]``; returns the checked entry."""
        try:
            fault = FaultKind(kind)
        except ValueError:
            raise BadValue(f"inject: unknown fault kind {kind!r} "
                           f"(known: {', '.join(k.value for k in FaultKind)})") from None
        if self._clock is None:
            raise UserError("inject: these faults are on no run yet")
        now_s = (self._clock.t_us - self._t0_us) * 1e-6
        params.setdefault("at_s", now_s)
        e = FaultEntry.parse(fault, params, "inject")
        if e.at_s < now_s:
            raise BadValue(f"inject: at_s {e.at_s:g} is in the past (now {now_s:g} s)")
        self.entries.append(e)
        self._schedule(e)
        return e

    def switch_bits(self, t_us: int, bits: int,
                    contacts: Callable[[], Sequence[bool]] | None = None) -> int:
        """The six limit-switch bits as the firmware reads them, stuck or bouncing legs
        applied: a bouncing contact flips every half period from the true level; a swing
        press (``contacts``: the world's loaded feet) presses it in the leg's swing."""
        if self._swings and contacts is not None:
            feet = contacts()
            for leg, swing in self._swings.items():
                if swing.pressed(t_us, feet[leg], self.report):
                    bits |= 1 << leg
        for leg, (e, since_us) in self._switches.items():
            bit = 1 << leg
            if e.pressed is not None:
                level = e.pressed
            else:
                half_us = max(1, int(e.period_s * 5e5))
                level = bool(bits & bit) ^ bool(((t_us - since_us) // half_us) & 1)
            bits = (bits | bit) if level else (bits & ~bit)
        return bits

    def apply_due(self, t_us: int) -> None:
        """Fire every timed fault due at or before t_us."""
        while self._events and self._events[0][0] <= t_us:
            te, _, start, e = self._events.pop(0)
            self._fire(te, start, e)
        self.next_us = self._events[0][0] if self._events else NEVER_US

    def can_frame(self, arb_id: int, data: bytes) -> tuple[int, bytes] | None:
        """The CAN sensor node's frame as it goes out: None while it is silent, a garbage
        frame (an ID and bytes our DBC does not define, seeded) while it babbles."""
        if self._can_node is FaultKind.CAN_SILENT:
            return None
        if self._can_node is FaultKind.CAN_GARBAGE:
            rng = self._garbage_rng
            return 0x700 + rng.randrange(0x100), bytes(rng.randrange(256) for _ in range(8))
        return arb_id, data

    def force_sample(self, f: tuple[float, float, float]) -> tuple[float, float, float] | None:
        """A force sample as the sensor sends it: biased, or None while it drops out."""
        if self._force_dropout:
            return None
        if self._force_bias is None:
            return f
        return f[0] + self._force_bias[0], f[1], f[2] + self._force_bias[1]

    def _fire(self, t_us: int, start: bool, e: FaultEntry) -> None:
        kind = e.kind.value
        name = kind if start else kind + "_end"
        if e.kind in FORCE_KINDS:
            fz_n = e.fz_n or 0.0
            if e.kind is FaultKind.FORCE_BIAS:
                self._force_bias = (e.fx_n, fz_n) if start else None
                detail = (f"force sensor biased by fx {e.fx_n:+g} N, fz {fz_n:+g} N"
                          if start else "force sensor unbiased")
            else:
                self._force_dropout = start
                detail = "force sensor silent" if start else "force sensor back"
            self.report(t_us, name, detail)
            return
        if e.kind in STATUS_KINDS:
            faults = self._status.setdefault(e.id, [])
            if start:
                faults.append(e)
            elif e in faults:
                faults.remove(e)
            self.report(t_us, name, f"id {e.id}: " + (_STATUS_SAYS[e.kind] if start
                                                      else "status packets sent as they are"))
            return
        if e.kind in BUS_CAN_KINDS:
            if start:
                self.can_faults.append(e)
            elif e in self.can_faults:
                self.can_faults.remove(e)
            self.report(t_us, name, ("CAN frames " + _CAN_SAYS[e.kind]) if start
                        else "CAN frames delivered as sent")
            return
        if e.kind in CAN_KINDS:
            self._can_node = e.kind if start else None
            self.report(t_us, name,
                        "the CAN sensor node " + ("silent" if e.kind is FaultKind.CAN_SILENT
                                                  else "sends garbage frames") if start
                        else "the CAN sensor node speaks normally again")
            return
        if e.kind is FaultKind.SWITCH_SWING_PRESS:
            if start:
                self._swings[e.leg] = SwingPress(e)
            else:
                self._swings.pop(e.leg, None)
            self.report(t_us, name, f"leg {e.leg}: " + (
                f"pressed {e.press_s:g} s once its foot is {e.after_s:g} s in the air, each "
                "swing" if start else "released to the true level"))
            return
        if e.kind in SWITCH_KINDS:
            if start:
                self._switches[e.leg] = (e, t_us)
                detail = (f"pressed {str(e.pressed).lower()}" if e.pressed is not None
                          else f"chatter period {e.period_s:g} s")
            else:
                self._switches.pop(e.leg, None)
                detail = "released to the true level"
            self.report(t_us, name, f"leg {e.leg}: {detail}")
            return
        if e.kind is FaultKind.ID_CONFLICT and not start:
            s = self._conflicts.pop(id(e), None)
            if s is not None:
                s.set_id(e.id, t_us)
                self.bus._reindex()
            self.report(t_us, name, f"id {e.id}: its own ID again")
            return
        bus = self.bus
        ids = e.ids or ([e.id] if e.id is not None else [s.id for s in bus.servos])
        for dev_id in ids:
            s = bus.servo(dev_id)
            if s is None:
                self.report(t_us, kind, f"id {dev_id}: no such servo, nothing injected")
                continue
            if e.kind is FaultKind.UNPLUG:
                bus.set_plugged(s, not start, t_us)
                detail = "unplugged" if start else "plugged back (power-cycled)"
            elif e.kind is FaultKind.STALL:
                s.set_stalled(start, t_us)
                detail = "stalled by an external load" if start else "load removed"
            elif e.kind is FaultKind.OVERHEAT:
                s.set_hot_spot(e.temperature_c if start else None, t_us)
                detail = (f"heating towards {e.temperature_c:g} C" if start
                          else "heat source removed")
            elif e.kind in SERVO_STATE_KINDS:
                detail = self._servo_fault(start, e, s, t_us)
            else:
                s.set_supply_v(e.volts if start else SUPPLY_V, t_us)
                detail = f"supply {e.volts:g} V" if start else f"supply back to {SUPPLY_V:g} V"
            self.report(t_us, name, f"id {dev_id}: {detail}")

    def _servo_fault(self, start: bool, e: FaultEntry, s: Any, t_us: int) -> str:
        """A fault of the issue-42 vocabulary on servo ``s``; its line for /faults."""
        if e.kind is FaultKind.BROWNOUT:
            s.power_cycle(t_us)
            return "supply dipped: rebooted, torque off, RAM back to its defaults"
        if e.kind is FaultKind.OVERLOAD:
            s.advance_to(t_us)
            s.health.overload = True
            return "Overload error bit set (torque off where Alarm Shutdown has it)"
        if e.kind is FaultKind.ID_CONFLICT:
            self._conflicts[id(e)] = s
            s.set_id(e.as_id, t_us)
            self.bus._reindex()
            return f"answers as id {e.as_id} too (two servos, one ID)"
        if not start:
            s.set_reading(None, t_us)
            return "Present Position reads true again"
        if e.kind is FaultKind.POSITION_STUCK:
            s.set_reading(StuckReading(), t_us)
            return "Present Position stuck"
        rng = random.Random(f"{self._seed}:noise:{e.id}:{e.at_s}")
        s.set_reading(NoisyReading(e.sigma, rng), t_us)
        return f"Present Position noisy, sigma {e.sigma:g} units"

    def status_bursts(self, dev_id: int, data: bytearray, start_us: int, wire_us: int,
                      protocol: int = 1) -> list[tuple[int, bytearray]]:
        """Servo ``dev_id``'s status packet ``data`` (Dynamixel ``protocol`` 1 or 2), due on
        the line at ``start_us``, as the status faults active on it send it: (start, bytes)
        of each burst, none when it is lost. ``wire_us`` is the packet's own time on the
        wire (a twin answers after it)."""
        faults = self._status.get(dev_id)
        if not faults:
            return [(start_us, data)]
        out = [(start_us, data)]
        for e in faults:
            kind = e.kind
            if kind is FaultKind.STATUS_MISSING:
                return []
            if kind is FaultKind.STATUS_LATE:
                out = [(t + int(round(e.delay_s * 1e6)), d) for t, d in out]
            elif kind is FaultKind.STATUS_TWIN:
                out = out + [(out[-1][0] + wire_us, bytearray(out[-1][1]))]
            else:
                out = [(t, mangled(kind, e, d, protocol)) for t, d in out]
        return out

    def can_mangle(self, data: bytes) -> tuple[str, int, bytes]:
        """What the CAN faults active now do to a frame's ``data``: (``"drop"``, ``"hold"``
        or ``"send"``, how long it is held in us (-1: until the next frame has gone), the
        bytes sent: garbage of the same length while ``can_corrupt`` lasts, seeded)."""
        verdict, delay_us = "send", 0
        for e in self.can_faults:
            if e.kind is FaultKind.CAN_DROPPED:
                return "drop", 0, data
            if e.kind is FaultKind.CAN_CORRUPT:
                data = bytes(self._can_rng.randrange(256) for _ in range(len(data)))
            elif e.kind is FaultKind.CAN_DELAYED:
                verdict, delay_us = "hold", int(round(e.delay_s * 1e6))
            elif verdict == "send":
                verdict, delay_us = "hold", -1
        return verdict, delay_us, data

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


_STATUS_SAYS = {
    FaultKind.STATUS_CHECKSUM: "status packets with a wrong checksum",
    FaultKind.STATUS_WRONG_ID: "status packets carry another ID",
    FaultKind.STATUS_TRUNCATED: "status packets cut short by their last byte",
    FaultKind.STATUS_PADDED: "status packets with one parameter too many",
    FaultKind.STATUS_ERROR: "status packets with error bits set",
    FaultKind.STATUS_LATE: "status packets sent late",
    FaultKind.STATUS_MISSING: "status packets never sent",
    FaultKind.STATUS_TWIN: "a twin sends each status packet again",
}
_CAN_SAYS = {FaultKind.CAN_DROPPED: "lost", FaultKind.CAN_DELAYED: "delayed",
             FaultKind.CAN_REORDERED: "swapped with the next", FaultKind.CAN_CORRUPT:
             "with garbage data"}
