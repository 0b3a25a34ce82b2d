# What the Dynamixel protocol scripts share (mpy_dynamixel.py, mpy_v2_packets.py), the
# same under micropython and CPython: deterministic numbers, the stream round trip and the
# byte path's allocation check, each given the protocol module.
import sys

from tests.micropython.checks import check


class Lcg:
    """Pseudo-random numbers, the same in both interpreters: ``rnd(n)`` is in 0..n-1."""

    def __init__(self, seed):
        self.seed = seed

    def __call__(self, n):
        self.seed = (self.seed * 1103515245 + 12345) & 0x7FFFFFFF
        return self.seed % n


def round_trip(dx, rnd, makers, ids, count):
    """``count`` packets, each ``makers[kind](dev)`` for a random kind and ID below ``ids``,
    some with garbage (no FF) before them, fed to a new parser as one stream: every packet
    must come back. Prints the counts for the pytest side to compare."""
    stream = bytearray()
    want = []
    for _ in range(count):
        kind = rnd(len(makers))
        pkt = makers[kind](rnd(ids))
        if rnd(4) == 0:
            stream.extend(bytes(rnd(255) for _ in range(1 + rnd(5))))
        stream.extend(pkt)
        want.append(pkt)
    p = dx.Parser()
    got = p.feed(stream)
    check([q.raw for q in got] == want, "round trip of %d packets" % len(want))
    print("stream", len(stream), "packets", p.packets, "garbage", p.garbage)


def _allocated_by_byte_path(dx, instr, params, nparams, data, length):
    """Bytes allocated while building 20 packets and parsing ``data`` 20 times (locals only)."""
    import gc

    buf = bytearray(dx.MAX_PACKET)
    p = dx.Parser()
    push = p.push
    n = 0
    gc.collect()
    gc.disable()
    before = gc.mem_alloc()
    for _ in range(20):
        n = dx.build_into(buf, 1, instr, params, nparams)
        for i in range(len(data)):
            push(data[i], i)
    after = gc.mem_alloc()
    gc.enable()
    check(p.packets == 20 and n == length, "parsed while measuring")
    return after - before


def byte_path_allocates_nothing(dx, instr, params, nparams, data, length):
    """``build_into`` (a ``length``-byte packet of ``params[:nparams]``) and ``push`` (of
    the packet ``data``) do not allocate; MicroPython only: CPython boxes every int."""
    if sys.implementation.name == "micropython":
        grew = _allocated_by_byte_path(dx, instr, params, nparams, data, length)
        check(grew == 0, "byte path allocated %d bytes" % grew)
