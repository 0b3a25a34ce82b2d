"""The Protocol 2.0 stream parser (protocol/dynamixel/v2.py) under hostile streams: garbage
(noise, packets hit by bit errors, cut-off packets, headers promising more than comes,
stuffed payloads), then after an idle gap one valid packet the parser must find again."""
from __future__ import annotations

from fuzz.hostile import Rng
from fuzz.tally import Budget, Tally
from hexhil.protocol.dynamixel import v2 as dx2

GAP_US = dx2.INTER_BYTE_TIMEOUT_US + 1
BATCH = 2000


def valid_packet(rng: Rng) -> bytes:
    """A valid instruction or status packet; parameters rich in FF and FD (stuffing)."""
    n = rng.below(8) if rng.below(8) else rng.below(60)
    params = bytes((0xFF, 0xFD, rng.below(256))[rng.below(3)] for _ in range(n))
    instr = (dx2.STATUS, dx2.WRITE, dx2.SYNC_WRITE, rng.below(256))[rng.below(4)]
    dev_id = rng.below(0xFD)
    if instr == dx2.STATUS:
        params = bytes((rng.below(256),)) + params
    return dx2.packet(dev_id, instr, params)


def garbage(rng: Rng) -> bytes:
    kind = rng.below(5)
    if kind == 0:
        return bytes((0xFF, 0xFD, 0x00, rng.below(256))[rng.below(4)] for _ in range(rng.below(40)))
    if kind == 1:
        out = bytearray(valid_packet(rng))
        for _ in range(1 + rng.below(3)):
            out[rng.below(len(out))] ^= 1 << rng.below(8)
        return bytes(out)
    if kind == 2:
        p = valid_packet(rng)
        return p[:rng.below(len(p))]
    if kind == 3:  # a header promising up to 1,100 bytes
        n = rng.below(1100)
        return bytes((0xFF, 0xFF, 0xFD, 0x00, rng.below(0xFD), n & 0xFF, n >> 8))
    return dx2.fast_status([(0, 1 + k, bytes(rng.below(256) for _ in range(4)))
                            for k in range(1 + rng.below(4))])[:rng.below(60)]


def run(seed: int, budget_s: float | None, limit: int | None) -> list[Tally]:
    tally = Tally("protocol 2.0 parser (CPython)", "streams")
    budget = Budget(budget_s, limit)
    rng = Rng(seed)
    parser = dx2.Parser()
    t = 0
    while budget.more(tally.inputs):
        for _ in range(BATCH if limit is None else min(BATCH, limit - tally.inputs)):
            tally.inputs += 1
            junk, want = garbage(rng), valid_packet(rng)
            try:
                for b in junk:
                    t += 10
                    parser.push(b, t)
                t += GAP_US
                hit = False
                for b in want:
                    t += 10
                    if parser.push(b, t):
                        hit = parser.current().raw == want
                tally.resync_checked += 1
                tally.resync_found += hit
                if not hit and len(tally.notes) < 3:
                    tally.notes[f"missed at stream {tally.inputs}"] = want.hex()
            except Exception as exc:  # counted, never hidden: an escape fails the run
                tally.escape(f"stream {tally.inputs}: {exc.__class__.__name__}: {exc}")
                parser = dx2.Parser()
    tally.wall_s = budget.elapsed_s()
    return [tally]
