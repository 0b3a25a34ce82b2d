"""The CAN frame codecs (protocol/can_frames.py) against cantools and protocol/hexhil.dbc:
random payloads decode to the same values, re-encode to the same bytes, and random
signal values either encode or raise ValueError."""
from __future__ import annotations

import math
import random
from pathlib import Path

import cantools

from fuzz.tally import Budget, Tally
from hexhil.protocol import can_frames as cf

DBC = Path(cf.__file__).with_name("hexhil.dbc")


def _same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(math.isclose(a[k], b[k], rel_tol=1e-9, abs_tol=1e-12)
                                        for k in a)


def _unused_bits_cleared(name: str, data: bytes) -> bytes:
    """``data`` as cf.encode writes it back: a bitfield's unused high bits dropped."""
    return cf.encode(name, **cf.decode(cf.FRAMES[name][0], data)[1])[1]


def run(seed: int, budget_s: float | None, limit: int | None) -> list[Tally]:
    db = cantools.database.load_file(str(DBC))
    rng = random.Random(seed)
    names = sorted(cf.FRAMES)
    tally = Tally("CAN frame codecs (= cantools)", "frames")
    budget = Budget(budget_s, limit)
    while budget.more(tally.inputs):
        tally.inputs += 1
        name = rng.choice(names)
        arb_id, _, sigs = cf.FRAMES[name]
        dlc = cf.DLC[name]
        try:
            if rng.random() < 0.1:  # an unknown ID or a short frame: ValueError, nothing else
                bad_id = rng.randrange(0x800)
                data = rng.randbytes(rng.randrange(dlc + 1))
                try:
                    cf.decode(bad_id if bad_id not in cf.BY_ID else arb_id, data[:dlc - 1])
                    tally.escape(f"decode accepted 0x{bad_id:03X} {data.hex()}")
                except ValueError:
                    pass
                continue
            data = rng.randbytes(dlc)
            theirs = db.decode_message(arb_id, data, decode_choices=False)
            ours = cf.decode(arb_id, data)[1]
            if not _same(ours, dict(theirs)):
                tally.escape(f"{name} {data.hex()}: ours {ours} cantools {theirs}")
            if any(s[1] == cf.ENUM and not s[3] <= ours[s[0]] <= s[4] for s in sigs):
                try:  # an enum outside its choices decodes (as in cantools), never encodes
                    cf.encode(name, **ours)
                    tally.escape(f"{name} {data.hex()}: enum out of range encoded")
                except ValueError:
                    tally.notes["enum out of range"] = tally.notes.get("enum out of range", 0) + 1
                continue
            again = _unused_bits_cleared(name, data)
            if db.encode_message(arb_id, ours) != again:
                tally.escape(f"{name} {data.hex()}: re-encoded differently from cantools")
            values = {s[0]: rng.choice((rng.uniform(-1e6, 1e6), rng.randrange(-9, 9), math.inf,
                                        -math.inf, math.nan)) for s in sigs}
            try:
                cf.encode(name, **values)
            except ValueError:
                pass
        except Exception as exc:  # an escape is what the fuzzer is for: count and report it
            tally.escape(f"{name}: {exc.__class__.__name__}: {exc}")
    tally.wall_s = budget.elapsed_s()
    return [tally]
