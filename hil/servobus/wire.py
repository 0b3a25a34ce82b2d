"""The UART under the servo bus: bytes as 8N1 bits in time, what a receiver at another baud
makes of them, and bursts of bytes on the line, which overlap as a wired AND (the idle-high
level losing to any driven low bit; hil/servobus/line.py moves them)."""
from __future__ import annotations

import functools

BITS_PER_BYTE = 10  # 8N1: start, 8 data, stop
US_BITS = 1_000_000 * BITS_PER_BYTE


def resample(data: bytes, from_bps: int, to_bps: int) -> bytes:
    """What an 8N1 UART at ``to_bps`` decodes from ``data`` sent back to back at ``from_bps``.

    Samples each bit in the middle of the receiver's bit time after a falling start
    edge; bytes with a framing error are kept (the AX-12's UART hands them on too).
    """
    if from_bps == to_bps:
        return bytes(data)
    return _resampled(bytes(data), from_bps, to_bps)


@functools.lru_cache(maxsize=256)
def _resampled(data: bytes, from_bps: int, to_bps: int) -> bytes:
    """``resample``'s work, once for every servo at one rate: each of them decodes the
    same burst (18 servos at a wrong rate made a 1 s run take minutes)."""
    bits: list[int] = []
    for b in data:
        bits.append(0)
        bits.extend((b >> k) & 1 for k in range(8))
        bits.append(1)
    n = len(bits)
    ratio = from_bps / to_bps  # receiver bit time, in sender bit times

    def level(t: float) -> int:
        i = int(t)
        return bits[i] if 0 <= i < n else 1

    out = bytearray()
    i = 0
    while i < n:
        if bits[i] != 0 or (i and bits[i - 1] != 1):
            i += 1
            continue
        te = float(i)
        if level(te + 0.5 * ratio):  # false start: the low was shorter than half a bit
            i += 1
            continue
        byte = 0
        for k in range(8):
            if level(te + (1.5 + k) * ratio):
                byte |= 1 << k
        out.append(byte)
        i = max(i + 1, int(te + 9.5 * ratio) + 1)
    return bytes(out)


class Burst:
    """Bytes sent back to back on the line from ``start_us`` (a reply, or echoed tx)."""

    __slots__ = ("start_us", "data", "read", "reply", "emitted")

    def __init__(self, start_us: int, data: bytearray, reply: bool) -> None:
        self.start_us = start_us
        self.data = data
        self.read = 0
        self.reply = reply
        self.emitted = False


def and_overlap(bursts: list[Burst], tx: bytearray, t0_us: int, t1_us: int, baud: int) -> bool:
    """Master bytes sent from ``t0_us`` to ``t1_us`` over the replies in ``bursts``: each
    reply byte whose middle falls inside becomes the wired AND with the master's byte then,
    in both. True when any did."""
    per = US_BITS / baud
    hit = False
    for b in bursts:
        if not b.reply:
            continue
        end = b.start_us + per * len(b.data)
        if end <= t0_us or b.start_us >= t1_us:
            continue
        for i in range(b.read, len(b.data)):
            mid = b.start_us + (i + 0.5) * per
            if t0_us <= mid < t1_us:
                j = int((mid - t0_us) / per)
                c = b.data[i] & tx[j]
                b.data[i] = c
                tx[j] = c
                hit = True
    return hit


def merge_burst(bursts: list[Burst], burst: Burst, baud: int) -> bool:
    """Add ``burst`` to ``bursts`` (kept in start order, never overlapping): into the one it
    overlaps as the wired AND, byte by byte, else on its own. True when two replies met."""
    per = US_BITS / baud
    for b in bursts:
        end = b.start_us + per * len(b.data)
        if burst.start_us < end and b.start_us < burst.start_us + per * len(burst.data):
            k = int(round((burst.start_us - b.start_us) / per))
            if k < 0:  # keep the earlier start
                b.data[0:0] = b"\xff" * -k
                b.start_us = burst.start_us
                k = 0
            for i, v in enumerate(burst.data):
                if k + i < len(b.data):
                    b.data[k + i] &= v
                else:
                    b.data.append(v)
            both = b.reply and burst.reply
            b.reply = b.reply or burst.reply
            return both
    bursts.append(burst)
    bursts.sort(key=lambda x: x.start_us)
    return False
