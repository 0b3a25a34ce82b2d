"""protocol/dynamixel/v1.py API details the conformance suite does not reach."""
from __future__ import annotations

from hexhil.protocol.dynamixel import v1 as dxl


def test_reset_drops_the_partial_packet() -> None:
    p = dxl.Parser()
    p.feed(dxl.ping(1)[:4])
    assert p.pending() == 4
    p.reset()  # the line was turned round
    assert p.pending() == 0
    assert [q.id for q in p.feed(dxl.ping(2))] == [2]


def test_fields_after_push_and_u16_params() -> None:
    p = dxl.Parser()
    pkt = dxl.status(7, dxl.ERR_RANGE, (700).to_bytes(2, "little"))
    done = [p.push(b) for b in pkt]
    assert done == [False] * (len(pkt) - 1) + [True]
    assert (p.id, p.code, p.nparams) == (7, dxl.ERR_RANGE, 2)
    assert p.param_u16(0) == 700 == dxl.u16(p.param(0), p.param(1))
    assert bytes(p.buf[:len(pkt)]) == pkt


def test_build_into_uses_only_nparams_of_a_preallocated_buffer() -> None:
    buf = bytearray(dxl.MAX_PACKET)
    params = bytearray(b"\x1e\x00\x02\xff\xff\xff")  # stale bytes after the first three
    n = dxl.build_into(buf, 3, dxl.WRITE, params, 3)
    assert bytes(buf[:n]) == dxl.write(3, 30, b"\x00\x02")


def test_counters_add_up_over_a_noisy_stream() -> None:
    stream = (b"\x00\x01" + dxl.ping(1) + b"\xff\xff\x01\x02\x01\x00"  # bad checksum
              + dxl.status(1) + b"\xff\xff\x02\x00" + dxl.read(2, 36, 2))  # bad length
    p = dxl.Parser()
    out = p.feed(stream) + p.flush()
    assert [(q.id, q.code) for q in out] == [(1, dxl.PING), (1, 0), (2, dxl.READ)]
    c = p.counters()
    assert (c["packets"], c["bad_checksum"], c["bad_length"], c["timeouts"]) == (3, 1, 1, 0)
    assert c["garbage"] >= 2


def test_max_length_packet() -> None:
    pkt = dxl.status(1, 0, bytes(range(253)))  # LEN 255, the most a byte holds
    assert len(pkt) == dxl.MAX_PACKET
    assert dxl.Parser().feed(pkt)[0].params == bytes(range(253))


def _state(p: dxl.Parser) -> tuple:
    return (p.id, p.code, p.nparams, p.packets, p.garbage, p.bad_checksum,
            bytes(p.buf[:p.pending() + p._consumed]), p.pending())


def test_take_whole_leaves_the_state_pushing_byte_by_byte_leaves() -> None:
    """The firmware's one-call path for a reply (firmware/servo_bus/v1.py) must be exactly the
    per-byte parse: same fields, buffer and counters; anything else is refused untouched."""
    status = dxl.status(7, dxl.ERR_OVERLOAD, bytes((1, 2, 3, 4, 5, 6)))
    data = b"\x00\x01" + status
    whole, byte = dxl.Parser(), dxl.Parser()
    assert whole.take_whole(data, 2, len(data))
    assert [byte.push(b) for b in status][-1]
    assert _state(whole) == _state(byte)
    assert whole.param_u16(4) == byte.param_u16(4) == 0x0605
    for bad in (status[:-1] + bytes((status[-1] ^ 1,)), status[:-1], b"\xff" + status,
                status + b"\x00", b"\xff\xff\x07\x01\x00\xf7"):
        p = dxl.Parser()
        before = _state(p)
        assert not p.take_whole(bad, 0, len(bad))
        assert _state(p) == before
    busy = dxl.Parser()
    busy.push(0xFF)
    assert not busy.take_whole(status, 0, len(status))
