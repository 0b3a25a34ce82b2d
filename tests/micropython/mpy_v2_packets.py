# protocol/dynamixel/v2.py under the real micropython binary (checks.py asserts, no pytest).
# Prints lines the pytest side compares with CPython's, then "OK v2_packets <checks>".
from protocol.dynamixel import v2 as dx2
from tests.micropython.checks import check, done
from tests.micropython.packet_checks import Lcg, byte_path_allocates_nothing, round_trip


def hx(b):
    return "".join("%02x" % x for x in b)


# Golden vectors of the ROBOTIS Protocol 2.0 e-manual.
check(hx(dx2.ping(1)) == "fffffd0001030001194e", "ping")
check(hx(dx2.read(1, 132, 4)) == "fffffd0001070002840004001d15", "read")
check(hx(dx2.status(1, 0, b"\x06\x04\x26")) == "fffffd000107005500060426655d", "ping reply")
check(hx(dx2.sync_read(132, 4, [1, 2])) == "fffffd00fe090082840004000102cefa", "sync read")
check(hx(dx2.write(1, 0, b"\xff\xff\xfd\xff")) == "fffffd00010a00030000fffffdfdff6396", "stuffed")

rnd = Lcg(4321)


def data(n):
    return bytes((0xFF, 0xFD, rnd(256))[rnd(3)] for _ in range(n))


# Round trips of packets full of FF and FD (stuffing), some as fast replies.
round_trip(dx2, rnd, (
    dx2.ping,
    lambda dev: dx2.read(dev, rnd(150), 1 + rnd(8)),
    lambda dev: dx2.write(dev, rnd(150), data(1 + rnd(8))),
    lambda dev: dx2.sync_write(116, 4, [(i, data(4)) for i in range(1 + rnd(18))]),
    lambda dev: dx2.bulk_read([(i, 132, 4) for i in range(1 + rnd(6))], rnd(2) == 1),
    lambda dev: dx2.fast_status([(0, i, data(4)) for i in range(1 + rnd(4))]),
    lambda dev: dx2.status(dev, rnd(256), data(rnd(6))),
), 253, 200)

bad = bytearray(dx2.ping(3))
bad[-1] ^= 1
p = dx2.Parser()
check([q.id for q in p.feed(bytes(bad) + dx2.ping(4))] == [4], "resync after bad crc")
check(p.bad_crc == 1 and p.last_reject == "bad_crc", "bad crc counted")
print("counters", sorted(p.counters().items()))

# build_into (a stuffed SYNC_WRITE) and push (20 stuffed SYNC_WRITEs) do not allocate.
byte_path_allocates_nothing(
    dx2, dx2.SYNC_WRITE, bytearray(b"\x74\x00\x04\x00\x01\xff\xff\xfd\x00"), 9,
    dx2.sync_write(116, 4, [(i, b"\xff\xff\xfd\x00") for i in range(18)]), 20)

done("v2_packets")
