"""Hostile Protocol 1.0 byte streams, generated the same under CPython and MicroPython.

MicroPython-compatible (no annotations, no f-strings, only the language core), so the one
generator feeds the host parser and ``fuzz/mpy_parser.py`` under the real ``micropython``
binary, and both print the same digests. A stream is garbage (random bytes, packets with
flipped bits, cut-off packets, runs of FF, a header with a large LEN) followed, after the
line has been idle longer than the AX-12's inter-byte timeout (100 ms), by one valid
packet: the parser must find that packet again ("resync").
"""
try:
    from hexhil.protocol.dynamixel import v1 as dxl   # the host: the installed package
except ImportError:
    from protocol.dynamixel import v1 as dxl          # micropython: the chip's names

GAP_US = dxl.INTER_BYTE_TIMEOUT_US + 1
MASK32 = 0xFFFFFFFF


class Rng:
    """xorshift32 (Marsaglia 2003): the same numbers in every Python."""

    def __init__(self, seed):
        self.s = ((seed * 2654435761) ^ 0x9E3779B9) & MASK32 or 1

    def next(self):
        x = self.s
        x ^= (x << 13) & MASK32
        x ^= x >> 17
        x ^= (x << 5) & MASK32
        self.s = x
        return x

    def below(self, n):
        return self.next() % n


def valid_packet(rng):
    """One valid instruction or status packet (any ID but FF, any code, 0-39 params)."""
    n = rng.below(6) if rng.below(8) else rng.below(40)
    params = bytearray(n)
    for i in range(n):
        params[i] = rng.below(256)
    return dxl.packet(rng.below(0xFF), rng.below(256), params)


def garbage(rng):
    """One of five kinds of garbage, 0-80 bytes."""
    kind = rng.below(5)
    if kind == 0:  # noise
        out = bytearray(rng.below(40))
        for i in range(len(out)):
            out[i] = rng.below(256) if rng.below(4) else 0xFF
        return out
    if kind == 1:  # a packet hit by bit errors
        out = bytearray(valid_packet(rng))
        for _ in range(1 + rng.below(3)):
            out[rng.below(len(out))] ^= 1 << rng.below(8)
        return out
    if kind == 2:  # a packet cut off
        p = valid_packet(rng)
        return bytearray(p[:rng.below(len(p))])
    if kind == 3:  # a header promising more than comes
        out = bytearray((0xFF, 0xFF, rng.below(0xFF), 2 + rng.below(254)))
        for _ in range(rng.below(20)):
            out.append(rng.below(256))
        return out
    out = bytearray()  # packets back to back, one of them damaged
    for _ in range(1 + rng.below(3)):
        out.extend(valid_packet(rng))
    if out:
        out[rng.below(len(out))] = rng.below(256)
    return out


def _mix(h, v):
    return (h * 31 + v) & MASK32


def run_parser(seed, count, report_every=0, out=None):
    """Feed ``count`` hostile streams to one long-lived Parser; return a tally tuple
    ``(inputs, bytes, escaped, resync_found, digest)``. With ``report_every`` a digest
    line goes to ``out`` (a list) every so many inputs, for CPython/MicroPython agreement.
    """
    rng = Rng(seed)
    parser = dxl.Parser()
    t = 0
    nbytes = escaped = found = 0
    h = 0
    for i in range(count):
        junk = garbage(rng)
        want = valid_packet(rng)
        try:
            for b in junk:
                t += 10
                if parser.push(b, t):
                    h = _mix(h, (parser.id << 16) | (parser.code << 8) | parser.nparams)
            t += GAP_US
            hit = False
            for b in want:
                t += 10
                if parser.push(b, t):
                    h = _mix(h, (parser.id << 16) | (parser.code << 8) | parser.nparams)
                    hit = parser.id == want[2] and parser.code == want[4] \
                        and bytes(parser.buf[0:len(want)]) == want
            if hit:
                found += 1
        except Exception:  # counted, never hidden: an escape fails the run
            escaped += 1
            parser = dxl.Parser()
        nbytes += len(junk) + len(want)
        if report_every and (i + 1) % report_every == 0 and out is not None:
            c = parser.counters()
            out.append("%d %08x %d %d %d %d %d %d" % (
                i + 1, h, c["packets"], c["garbage"], c["bad_length"], c["bad_checksum"],
                c["timeouts"], found))
    return count, nbytes, escaped, found, h
