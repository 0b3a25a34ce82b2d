# protocol/dynamixel/v1.py under the real micropython binary (checks.py asserts, no pytest).
# Prints lines the pytest side compares with CPython's, then "OK dynamixel <checks>".
from protocol.dynamixel import v1 as dxl
from tests.micropython.checks import check, done
from tests.micropython.packet_checks import Lcg, byte_path_allocates_nothing, round_trip


def unhex(s):
    s = s.replace(" ", "")
    return bytes(int(s[i:i + 2], 16) for i in range(0, len(s), 2))


# Golden vectors of the ROBOTIS Protocol 1.0 e-manual and the AX-12 manual.
check(dxl.ping(1) == unhex("FFFF010201FB"), "ping")
check(dxl.status(1) == unhex("FFFF010200FC"), "ping reply")
check(dxl.read(1, 43, 1) == unhex("FFFF0104022B01CC"), "read temperature")
check(dxl.status(1, 0, bytes((0x20,))) == unhex("FFFF01030020DB"), "read reply")
check(dxl.action() == unhex("FFFFFE0205FA"), "action")
check(dxl.factory_reset(0) == unhex("FFFF000206F7"), "factory reset")
check(dxl.reg_write(1, 30, bytes((0xF4, 0x01))) == unhex("FFFF0105041EF401E2"), "reg write")
check(dxl.write(0xFE, 3, bytes((1,))) == unhex("FFFFFE04030301F6"), "write")
sync = dxl.sync_write(0x1E, 4, [(0, unhex("10005001")), (1, unhex("20026003")),
                                (2, unhex("30007001")), (3, unhex("20028003"))])
check(sync == unhex("FFFFFE18831E04001000500101200260030230007001032002800312"), "sync write")
check(dxl.error_names(0x24) == ["overheating", "overload"], "error names")
# The firmware's one-pass SYNC_WRITE: the same packet as sync_write, for every value's bytes.
ids = list(range(1, 19))
first = [(j * 977 + 5) % 1024 for j in range(18)]
second = [(j * 131 + 255) % 2048 for j in range(18)]
buf = bytearray(dxl.MAX_PACKET)
n = dxl.sync_write_into(buf, 0x1E, ids, first, second)
want = dxl.sync_write(0x1E, 4, [(ids[j], bytes((first[j] & 0xFF, first[j] >> 8, second[j] & 0xFF,
                                                second[j] >> 8))) for j in range(18)])
check(bytes(buf[:n]) == want, "sync_write_into is sync_write")

# Round trips over a deterministic pseudo-random stream (same numbers in both interpreters).
rnd = Lcg(12345)


def random_bytes(n):
    return bytes(rnd(256) for _ in range(n))


def sync_write(dev):
    n = 1 + rnd(4)
    return dxl.sync_write(rnd(50), n, [(i, random_bytes(n)) for i in range(1 + rnd(18))])


round_trip(dxl, rnd, (
    dxl.ping,
    lambda dev: dxl.read(dev, rnd(50), 1 + rnd(50)),
    lambda dev: dxl.write(dev, rnd(50), random_bytes(1 + rnd(8))),
    lambda dev: dxl.reg_write(dev, rnd(50), random_bytes(1 + rnd(8))),
    dxl.action,
    dxl.factory_reset,
    sync_write,
    lambda dev: dxl.status(dev, rnd(128), random_bytes(rnd(6))),
), 254, 300)

# Bad checksum, bad length, resync, timeout, flush.
p = dxl.Parser()
check(p.feed(unhex("FFFF010201FA") + dxl.ping(2))[0].id == 2, "resync after bad checksum")
check(p.bad_checksum == 1 and p.last_reject == "bad_checksum", "bad checksum counted")
p.feed(unhex("FFFF0101") + dxl.ping(3))
check(p.bad_length == 1, "bad length counted")
p = dxl.Parser()
for b in dxl.ping(4)[:3]:
    p.push(b, 0)
p.push(2, 200000)
check(p.timeouts == 1 and p.last_reject == "timeout", "timeout counted")
p = dxl.Parser()
hidden = unhex("FFFF07F0") + dxl.ping(5)  # a garbage header whose LEN hides the ping
check(p.feed(hidden) == [], "hidden while the long packet may complete")
check([q.id for q in p.flush()] == [5], "flush recovers it")
print("counters", sorted(p.counters().items()))

# build_into (a WRITE) and push (20 SYNC_WRITEs) do not allocate.
byte_path_allocates_nothing(
    dxl, dxl.WRITE, bytearray(b"\x1e\x04\x00\x02\x00\x01"), 6,
    dxl.sync_write(30, 4, [(i, b"\x00\x02\x00\x01") for i in range(18)]), 12)

done("dynamixel")
