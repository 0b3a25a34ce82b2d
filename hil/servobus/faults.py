"""Fault injection on the servo bus, from a scenario's ``[faults]`` or ``hexhil bus`` flags.

Line faults (bit errors, dropped status packets) draw from seeded RNGs, one stream each,
so a scenario and a seed give the same faults byte for byte. Timed faults fire at exact
virtual microseconds: a servo unplugged, stalled by an external load, overheating; supply
voltage sag; and the vocabulary of issue 42 (docs/servo-bus.md "Fault vocabulary"): a
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
    "brownout": {"id": (int, True), "at_s": (float, True)},
    "overload": {"id": (int, True), "at_s": (float, True)},
    "position_stuck": {"id": (int, True), "at_s": (float, True), "until_s": (float, False)},
    "position_noise": {"id": (int, True), "at_s": (float, True), "until_s": (float, False),
                       "sigma": (float, True)},
    "id_conflict": {"id": (int, True), "as_id": (int, True), "at_s": (float, True),
                    "until_s": (float, False)},
    "switch_stuck": {"leg": (int, True), "pressed": (bool, True), "at_s": (float, True),
                     "until_s": (float, False)},
    "switch_bounce": {"leg": (int, True), "period_s": (float, True), "at_s": (float, True),
                      "until_s": (float, False)},
    "can_silent": {"at_s": (float, True), "until_s": (float, False)},
    "can_garbage": {"at_s": (float, True), "until_s": (float, False)},
    "force_bias": {"at_s": (float, True), "until_s": (float, False), "fx_n": (float, True),
                   "fz_n": (float, False)},
    "force_dropout": {"at_s": (float, True), "until_s": (float, False)},
}
KINDS = tuple(_ENTRY_KEYS)
SWITCH_KINDS = ("switch_stuck", "switch_bounce")
CAN_KINDS = ("can_silent", "can_garbage")
FORCE_KINDS = ("force_bias", "force_dropout")   # seed 000's force sensor (hil/world/beams_node.py)


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
        if not isinstance(v, want) or (isinstance(v, bool) and want is not bool):
            raise UserError(f"{where}: '{kind}.{k}' must be {want.__name__}, got {v!r}")
        out[k] = v
    for k, (_, required) in keys.items():
        if required and k not in out:
            raise UserError(f"{where}: a '{kind}' entry needs '{k}'")
    if out["at_s"] < 0 or ("until_s" in out and out["until_s"] <= out["at_s"]):
        raise UserError(f"{where}: '{kind}' needs 0 <= at_s < until_s, got {raw!r}")
    for i in out.get("ids", [out.get("id", 1)]) + ([out["as_id"]] if "as_id" in out else []):
        if not isinstance(i, int) or not 0 <= i <= 253:
            raise UserError(f"{where}: '{kind}' servo id must be 0-253, got {i!r}")
    if not 0 <= out.get("leg", 0) <= 5:
        raise UserError(f"{where}: '{kind}.leg' must be 0-5 (LF, LM, LH, RF, RM, RH), "
                        f"got {out['leg']}")
    if out.get("sigma", 0.0) < 0 or out.get("period_s", 1.0) <= 0:
        raise UserError(f"{where}: '{kind}' needs sigma >= 0 and period_s > 0, got {raw!r}")
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
                 where: str = "faults", **timed: list | tuple) -> None:
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
        unknown = set(timed) - set(KINDS)
        if unknown:
            raise UserError(f"{where}: unknown fault kind {sorted(unknown)[0]!r} "
                            f"(known: {', '.join(KINDS)})")
        timed.update(unplug=unplug, stall=stall, overheat=overheat, voltage_sag=voltage_sag)
        self.entries = {k: [_entry(k, e, where) for e in timed.get(k, ())] for k in KINDS}
        self._seed = seed
        self._events: list[tuple[int, int, str, bool, dict[str, Any]]] = []
        self._seq = 0
        self._t0_us = 0
        self._clock: Any = None                                       # set by start
        self._switches: dict[int, tuple[dict[str, Any], int]] = {}   # leg -> (entry, since)
        self._conflicts: dict[int, Any] = {}                          # id(entry) -> servo
        self._can_node: str | None = None                             # a CAN_KINDS, or None
        self._garbage_rng = random.Random(f"{seed}:can_garbage")
        self._force_bias: tuple[float, float] | None = None           # (fx_n, fz_n) added
        self._force_dropout = False
        self.next_us = NEVER_US
        self.bus = None

    @classmethod
    def from_scenario(cls, section: dict[str, Any], seed: int = 0, where: str = "faults",
                      on_fault: OnFault | None = None) -> "Faults":
        """From a loaded scenario's ``[faults]`` table (keys checked by hil.scenario)."""
        return cls(seed=seed, bit_error_rate=section.get("bit_error_rate", 0.0),
                   drop_status_rate=section.get("drop_status_rate", 0.0), on_fault=on_fault,
                   where=where, **{k: section.get(k, []) for k in KINDS})

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
        for kind, entries in self.entries.items():
            for e in entries:
                self._schedule(kind, e)

    def _schedule(self, kind: str, e: dict[str, Any]) -> None:
        for start, key in ((True, "at_s"), (False, "until_s")):
            if key in e:
                self._events.append((self._t0_us + int(round(e[key] * 1e6)), self._seq, kind,
                                     start, e))
                self._seq += 1
        self._events.sort(key=lambda ev: (ev[0], ev[1]))
        self.next_us = self._events[0][0] if self._events else NEVER_US

    def inject(self, kind: str, **params: Any) -> dict[str, Any]:
        """A timed fault at run time (the API, a host node, ``hexhil bus``): ``at_s`` (run
        time, default now) and ``until_s`` as in ``[faults]``; returns the checked entry."""
        if kind not in KINDS:
            raise UserError(f"inject: unknown fault kind {kind!r} (known: {', '.join(KINDS)})")
        if self._clock is None:
            raise UserError("inject: these faults are on no run yet")
        now_s = (self._clock.t_us - self._t0_us) * 1e-6
        params.setdefault("at_s", now_s)
        e = _entry(kind, params, "inject")
        if e["at_s"] < now_s:
            raise UserError(f"inject: at_s {e['at_s']:g} is in the past (now {now_s:g} s)")
        self.entries[kind].append(e)
        self._schedule(kind, e)
        return e

    def switch_bits(self, t_us: int, bits: int) -> int:
        """The six limit-switch bits as the firmware reads them, stuck or bouncing legs
        applied: a bouncing contact flips every half period from the true level."""
        for leg, (e, since_us) in self._switches.items():
            bit = 1 << leg
            if "pressed" in e:
                level = e["pressed"]
            else:
                half_us = max(1, int(e["period_s"] * 5e5))
                level = bool(bits & bit) ^ bool(((t_us - since_us) // half_us) & 1)
            bits = (bits | bit) if level else (bits & ~bit)
        return bits

    def apply_due(self, t_us: int) -> None:
        """Fire every timed fault due at or before t_us."""
        while self._events and self._events[0][0] <= t_us:
            te, _, kind, start, e = self._events.pop(0)
            self._fire(te, kind, start, e)
        self.next_us = self._events[0][0] if self._events else NEVER_US

    def can_frame(self, arb_id: int, data: bytes) -> tuple[int, bytes] | None:
        """The CAN sensor node's frame as it goes out: None while it is silent, a garbage
        frame (an ID and bytes our DBC does not define, seeded) while it babbles."""
        if self._can_node == "can_silent":
            return None
        if self._can_node == "can_garbage":
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

    def _fire(self, t_us: int, kind: str, start: bool, e: dict[str, Any]) -> None:
        if kind in FORCE_KINDS:
            if kind == "force_bias":
                self._force_bias = (e["fx_n"], e.get("fz_n", 0.0)) if start else None
                detail = (f"force sensor biased by fx {e['fx_n']:+g} N, fz {e.get('fz_n', 0.0):+g} N"
                          if start else "force sensor unbiased")
            else:
                self._force_dropout = start
                detail = "force sensor silent" if start else "force sensor back"
            self.report(t_us, kind if start else kind + "_end", detail)
            return
        if kind in CAN_KINDS:
            self._can_node = kind if start else None
            self.report(t_us, kind if start else kind + "_end",
                        "the CAN sensor node " + ("silent" if kind == "can_silent"
                                                  else "sends garbage frames") if start
                        else "the CAN sensor node speaks normally again")
            return
        if kind in SWITCH_KINDS:
            if start:
                self._switches[e["leg"]] = (e, t_us)
                detail = (f"pressed {str(e['pressed']).lower()}" if "pressed" in e
                          else f"chatter period {e['period_s']:g} s")
            else:
                self._switches.pop(e["leg"], None)
                detail = "released to the true level"
            self.report(t_us, kind if start else kind + "_end", f"leg {e['leg']}: {detail}")
            return
        if kind == "id_conflict" and not start:
            s = self._conflicts.pop(id(e), None)
            if s is not None:
                s.set_id(e["id"], t_us)
                self.bus._reindex()
            self.report(t_us, kind + "_end", f"id {e['id']}: its own ID again")
            return
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
            elif kind in ("brownout", "overload", "position_stuck", "position_noise",
                          "id_conflict"):
                detail = self._servo_fault(kind, start, e, s, t_us)
            else:
                s.set_supply_v(e["volts"] if start else SUPPLY_V, t_us)
                detail = f"supply {e['volts']:g} V" if start else f"supply back to {SUPPLY_V:g} V"
            self.report(t_us, kind if start else kind + "_end", f"id {dev_id}: {detail}")

    def _servo_fault(self, kind: str, start: bool, e: dict[str, Any], s: Any, t_us: int) -> str:
        """A fault of the issue-42 vocabulary on servo ``s``; its line for /faults."""
        if kind == "brownout":
            s.power_cycle(t_us)
            return "supply dipped: rebooted, torque off, RAM back to its defaults"
        if kind == "overload":
            s.advance_to(t_us)
            s.health.overload = True
            return "Overload error bit set (torque off where Alarm Shutdown has it)"
        if kind == "id_conflict":
            self._conflicts[id(e)] = s
            s.set_id(e["as_id"], t_us)
            self.bus._reindex()
            return f"answers as id {e['as_id']} too (two servos, one ID)"
        if not start:
            s.set_reading(None, t_us)
            return "Present Position reads true again"
        if kind == "position_stuck":
            s.set_reading(StuckReading(), t_us)
            return "Present Position stuck"
        rng = random.Random(f"{self._seed}:noise:{e['id']}:{e['at_s']}")
        s.set_reading(NoisyReading(e["sigma"], rng), t_us)
        return f"Present Position noisy, sigma {e['sigma']:g} units"

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


class StuckReading:
    """Present Position frozen at what it read when the fault began."""

    def __init__(self) -> None:
        self.units: int | None = None

    def apply(self, units: int) -> int:
        if self.units is None:
            self.units = units
        return self.units


class NoisyReading:
    """Present Position plus Gaussian noise of ``sigma`` units, from a seeded stream."""

    def __init__(self, sigma: float, rng: random.Random) -> None:
        self.sigma, self.rng = sigma, rng

    def apply(self, units: int) -> int:
        return int(round(units + self.rng.gauss(0.0, self.sigma)))
