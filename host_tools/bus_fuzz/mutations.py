"""The fuzzer's inputs: a few faults of the ``[faults]`` vocabulary (hil/scenario/faults_section.py),
each placed in virtual time inside the fuzzed window, drawn and changed by a seeded RNG.

A ``Mutation`` is one ``[faults]`` entry as data (its kind and its keys), so an input is
written out as a scenario's ``[faults]`` unchanged and replays without the fuzzer. Times
are whole milliseconds: TOML writes them back exactly.
"""
from __future__ import annotations

import random
from dataclasses import dataclass
from typing import Any, Sequence

from hexhil.hil.scenario.faults_section import FaultEntry, FaultKind

MAX_FAULTS = 8          # in one input
ERROR_BITS = {1: (1, 2, 4, 8, 16, 32, 64),       # the AX-12's error byte, one bit each
              2: (1, 2, 3, 4, 5, 6, 7, 128)}     # Protocol 2.0's: an error number, the alert
LATE_S = (0.0002, 0.0005, 0.001, 0.002, 0.005, 0.02)   # around and past the master's timeout
FOREIGN_IDS = (0, 100, 200, 253)        # IDs no walking servo has: half the wrong IDs drawn


@dataclass(frozen=True)
class Mutation:
    """One ``[faults]`` entry: its kind and its keys, in the order written."""

    kind: FaultKind
    keys: tuple[tuple[str, Any], ...]

    @property
    def at_s(self) -> float:
        return dict(self.keys)["at_s"]

    def entry(self) -> dict[str, Any]:
        return dict(self.keys)

    def checked(self) -> "Mutation":
        """Itself, after the scenario's own rules (``FaultEntry.parse``) accepted it."""
        FaultEntry.parse(self.kind, self.entry(), "fuzz")
        return self

    def __str__(self) -> str:
        return f"{self.kind.value} {{{', '.join(f'{k} = {v}' for k, v in self.keys)}}}"


Input = tuple[Mutation, ...]


@dataclass(frozen=True)
class Vocabulary:
    """What may be drawn: the kinds, the servo IDs and legs, the window [start_s, end_s),
    the line's Dynamixel protocol (its status packets' error byte)."""

    kinds: tuple[FaultKind, ...]
    ids: tuple[int, ...]
    start_s: float
    end_s: float
    legs: tuple[int, ...] = (0, 1, 2, 3, 4, 5)
    protocol: int = 1


DEFAULT_KINDS = (
    FaultKind.STATUS_CHECKSUM, FaultKind.STATUS_WRONG_ID, FaultKind.STATUS_TRUNCATED,
    FaultKind.STATUS_PADDED, FaultKind.STATUS_ERROR, FaultKind.STATUS_LATE,
    FaultKind.STATUS_MISSING, FaultKind.STATUS_TWIN, FaultKind.SWITCH_BOUNCE,
    FaultKind.SWITCH_STUCK, FaultKind.SWITCH_SWING_PRESS, FaultKind.CAN_DROPPED, FaultKind.CAN_DELAYED,
    FaultKind.CAN_REORDERED, FaultKind.CAN_CORRUPT, FaultKind.BROWNOUT, FaultKind.OVERLOAD,
    FaultKind.POSITION_STUCK, FaultKind.POSITION_NOISE, FaultKind.UNPLUG)


def _ms(t_s: float) -> float:
    return round(t_s, 3)


class Mutator:
    """Draws inputs and changes them; every draw comes from ``rng``."""

    def __init__(self, vocab: Vocabulary, rng: random.Random) -> None:
        self.v, self.rng = vocab, rng

    def _window(self) -> tuple[float, float]:
        """A start inside the window and a length from 1 ms to a third of it."""
        v, rng = self.v, self.rng
        at = _ms(rng.uniform(v.start_s, v.end_s - 0.001))
        length = _ms(max(0.001, (v.end_s - v.start_s) * rng.random() ** 2 / 3))
        return at, _ms(at + length)

    def fault(self) -> Mutation:
        """One fault of a kind drawn from the vocabulary."""
        rng, v = self.rng, self.v
        kind = rng.choice(v.kinds)
        at, until = self._window()
        keys: list[tuple[str, Any]]
        if kind in (FaultKind.BROWNOUT, FaultKind.OVERLOAD):
            keys = [("id", rng.choice(v.ids)), ("at_s", at)]
        elif kind is FaultKind.SWITCH_SWING_PRESS:     # each swing from at_s to the end
            keys = [("leg", rng.choice(v.legs)), ("after_s", _ms(rng.uniform(0.0, 0.5))),
                    ("press_s", _ms(rng.uniform(0.01, 0.1))), ("at_s", at)]
        elif kind in (FaultKind.SWITCH_STUCK, FaultKind.SWITCH_BOUNCE):
            keys = [("leg", rng.choice(v.legs))]
            keys.append(("pressed", rng.random() < 0.7) if kind is FaultKind.SWITCH_STUCK
                        else ("period_s", _ms(rng.uniform(0.002, 0.05))))
            keys += [("at_s", at), ("until_s", until)]
        elif kind.value.startswith("can_"):
            keys = [("at_s", at), ("until_s", until)]
            if kind is FaultKind.CAN_DELAYED:
                keys.append(("delay_s", _ms(rng.uniform(0.01, 0.5))))
        else:
            keys = [("id", rng.choice(v.ids))]
            if kind is FaultKind.STATUS_WRONG_ID:
                others = [i for i in v.ids if i != keys[0][1]]
                keys.append(("as_id", rng.choice(FOREIGN_IDS if rng.random() < 0.5 or not others
                                                 else others)))
            elif kind is FaultKind.STATUS_ERROR:
                keys.append(("bits", self._error_bits()))
            elif kind is FaultKind.STATUS_LATE:
                keys.append(("delay_s", rng.choice(LATE_S)))
            elif kind is FaultKind.POSITION_NOISE:
                keys.append(("sigma", float(rng.choice((5, 20, 80)))))
            keys += [("at_s", at), ("until_s", until)]
        return Mutation(kind, tuple(keys)).checked()

    def _error_bits(self) -> int:
        """One error of the line's error byte alone, or (a fifth of the time) a mix: any
        bits of the AX-12's seven; an error number with the alert bit on Protocol 2.0."""
        rng, one = self.rng, ERROR_BITS[self.v.protocol]
        if rng.random() < 0.8:
            return rng.choice(one)
        return rng.randrange(1, 128) if self.v.protocol == 1 else rng.choice(one[:-1]) | 128

    def fresh(self) -> Input:
        return ordered([self.fault() for _ in range(self.rng.randint(1, 3))])

    def mutate(self, base: Input, other: Input) -> Input:
        """``base`` changed once or twice: a fault added, removed, moved or redrawn, or the
        faults of ``other`` spliced in."""
        rng = self.rng
        faults = list(base)
        for _ in range(rng.randint(1, 2)):
            op = rng.random()
            if not faults or op < 0.35:
                faults.append(self.fault())
            elif op < 0.5:
                faults.pop(rng.randrange(len(faults)))
            elif op < 0.75:
                i = rng.randrange(len(faults))
                faults[i] = self._moved(faults[i])
            elif op < 0.9 or not other:
                faults[rng.randrange(len(faults))] = self.fault()
            else:
                faults += rng.sample(list(other), min(len(other), rng.randint(1, 2)))
        return ordered(faults[-MAX_FAULTS:])

    def _moved(self, m: Mutation) -> Mutation:
        """The same fault at another time in the window, its length kept."""
        keys = dict(m.keys)
        at = _ms(self.rng.uniform(self.v.start_s, self.v.end_s - 0.001))
        if "until_s" in keys:
            keys["until_s"] = _ms(at + keys["until_s"] - keys["at_s"])
        keys["at_s"] = at
        return Mutation(m.kind, tuple(keys.items())).checked()


def ordered(faults: Sequence[Mutation]) -> Input:
    """An input's canonical order: by time, then as written (duplicates dropped)."""
    out: list[Mutation] = []
    for m in sorted(faults, key=lambda m: (m.at_s, m.kind.value, m.keys)):
        if m not in out:
            out.append(m)
    return tuple(out)


def faults_table(faults: Input) -> dict[str, list[dict[str, Any]]]:
    """The input as ``[faults]`` keys: kind -> its entries."""
    out: dict[str, list[dict[str, Any]]] = {}
    for m in faults:
        out.setdefault(m.kind.value, []).append(m.entry())
    return out
