# protocol/dynamixel2.py under the real micropython binary (checks.py asserts, no pytest).
# Prints lines the pytest side compares with CPython's, then "OK dynamixel2 <checks>".
import sys

from protocol import dynamixel2 as dx2
from tests.micropython.checks import check, done


def hx(b):
    return "".join("%02x" % x for x in b)


# Golden vectors of the ROBOTIS Protocol 2.0 e-manual.
check(hx(dx2.ping(1)) == "fffffd0001030001194e", "ping")
check(hx(dx2.read(1, 132, 4)) == "fffffd0001070002840004001d15", "read")
check(hx(dx2.status(1, 0, b"\x06\x04\x26")) == "fffffd000107005500060426655d", "ping reply")
check(hx(dx2.sync_read(132, 4, [1, 2])) == "fffffd00fe090082840004000102cefa", "sync read")
check(hx(dx2.write(1, 0, b"\xff\xff\xfd\xff")) == "fffffd00010a00030000fffffdfdff6396", "stuffed")

seed = 4321


def rnd(n):
    global seed
    seed = (seed * 1103515245 + 12345) & 0x7FFFFFFF
    return seed % n


def data(n):
    return bytes((0xFF, 0xFD, rnd(256))[rnd(3)] for _ in range(n))


stream = bytearray()
want = []
for k in range(200):
    kind = rnd(7)
    dev = rnd(253)
    if kind == 0:
        pkt = dx2.ping(dev)
    elif kind == 1:
        pkt = dx2.read(dev, rnd(150), 1 + rnd(8))
    elif kind == 2:
        pkt = dx2.write(dev, rnd(150), data(1 + rnd(8)))
    elif kind == 3:
        pkt = dx2.sync_write(116, 4, [(i, data(4)) for i in range(1 + rnd(18))])
    elif kind == 4:
        pkt = dx2.bulk_read([(i, 132, 4) for i in range(1 + rnd(6))], rnd(2) == 1)
    elif kind == 5:
        pkt = dx2.fast_status([(0, i, data(4)) for i in range(1 + rnd(4))])
    else:
        pkt = dx2.status(dev, rnd(256), data(rnd(6)))
    if rnd(4) == 0:
        stream.extend(bytes(rnd(255) for _ in range(1 + rnd(5))))
    stream.extend(pkt)
    want.append(pkt)
p = dx2.Parser()
got = p.feed(stream)
check([q.raw for q in got] == want, "round trip of %d packets" % len(want))
print("stream", len(stream), "packets", p.packets, "garbage", p.garbage)

bad = bytearray(dx2.ping(3))
bad[-1] ^= 1
p = dx2.Parser()
check([q.id for q in p.feed(bytes(bad) + dx2.ping(4))] == [4], "resync after bad crc")
check(p.bad_crc == 1 and p.last_reject == "bad_crc", "bad crc counted")
print("counters", sorted(p.counters().items()))


def allocated_by_byte_path():
    """Bytes allocated while building 20 packets and parsing 20 stuffed SYNC_WRITEs."""
    import gc

    buf = bytearray(dx2.MAX_PACKET)
    params = bytearray(b"\x74\x00\x04\x00\x01\xff\xff\xfd\x00")
    p = dx2.Parser()
    raw = dx2.sync_write(116, 4, [(i, b"\xff\xff\xfd\x00") for i in range(18)])
    push = p.push
    n = 0
    gc.collect()
    gc.disable()
    before = gc.mem_alloc()
    for _ in range(20):
        n = dx2.build_into(buf, 1, dx2.SYNC_WRITE, params, 9)
        for i in range(len(raw)):
            push(raw[i], i)
    after = gc.mem_alloc()
    gc.enable()
    check(p.packets == 20 and n == 20, "parsed while measuring")
    return after - before


if sys.implementation.name == "micropython":
    grew = allocated_by_byte_path()
    check(grew == 0, "byte path allocated %d bytes" % grew)

done("dynamixel2")
