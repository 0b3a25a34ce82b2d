"""protocol/dynamixel/v2.py against the stock DynamixelSDK 4.1.0 packet builder (property
tests) and the e-manual's worked examples."""
from __future__ import annotations

from dynamixel_sdk import PacketHandler
from hypothesis import given, settings
from hypothesis import strategies as st

from hexhil.protocol.dynamixel import v2 as dx2

PH = PacketHandler(2.0)
INSTRS = sorted(set(dx2.INSTRUCTION_NAMES) - {dx2.STATUS})
ids = st.integers(0, dx2.MAX_ID) | st.just(dx2.BROADCAST_ID)
# payloads rich in FF and FD, so the stuffing pattern turns up often
payloads = st.lists(st.sampled_from([0xFF, 0xFD, 0x00, 0x55]) | st.integers(0, 255),
                    max_size=120).map(bytes)


def sdk_packet(dev_id: int, instr: int, params: bytes) -> bytes:
    """What the SDK's txPacket writes: its addStuffing, header and updateCRC."""
    tx = [0] * (len(params) + 10)
    tx[4] = dev_id
    tx[5] = (len(params) + 3) & 0xFF
    tx[6] = (len(params) + 3) >> 8
    tx[7] = instr
    tx[8:8 + len(params)] = list(params)
    tx = PH.addStuffing(tx)
    total = (tx[5] | tx[6] << 8) + 7
    tx[0:4] = [0xFF, 0xFF, 0xFD, 0x00]
    crc = PH.updateCRC(0, tx, total - 2)
    tx[total - 2] = crc & 0xFF
    tx[total - 1] = crc >> 8
    return bytes(tx[:total])


def test_emanual_examples() -> None:
    assert dx2.ping(1).hex() == "fffffd0001030001194e"
    assert dx2.ping().hex() == "fffffd00fe0300013142"
    assert dx2.status(1, 0, b"\x06\x04\x26").hex() == "fffffd000107005500060426655d"
    assert dx2.read(1, 132, 4).hex() == "fffffd0001070002840004001d15"
    assert dx2.write(1, 116, b"\x00\x02\x00\x00").hex() == "fffffd0001090003740000020000ca89"
    assert dx2.sync_read(132, 4, [1, 2]).hex() == "fffffd00fe090082840004000102cefa"
    assert dx2.bulk_read([(1, 0x90, 2), (2, 0x92, 1)]).hex().endswith("1a05")
    assert dx2.clear(1).hex().endswith("b1dc") and dx2.reboot(1).hex().endswith("2f4e")
    assert dx2.factory_reset(1, dx2.RESET_EXCEPT_ID).hex().endswith("a1e6")


def test_crc_table_is_the_sdks() -> None:
    data = bytes(range(256))
    assert dx2.crc16(data, 0, 256) == PH.updateCRC(0, list(data), 256)


@settings(max_examples=400, deadline=None)
@given(ids, st.sampled_from(INSTRS), payloads)
def test_builder_matches_the_sdk(dev_id: int, instr: int, params: bytes) -> None:
    assert dx2.packet(dev_id, instr, params) == sdk_packet(dev_id, instr, params)


@settings(max_examples=300, deadline=None)
@given(ids, st.sampled_from(INSTRS + [dx2.STATUS]), payloads, st.binary(max_size=20),
       st.binary(max_size=20))
def test_parser_unstuffs_through_garbage(dev_id: int, instr: int, params: bytes,
                                         before: bytes, after: bytes) -> None:
    if instr == dx2.STATUS and dev_id == dx2.BROADCAST_ID:
        dev_id = 1  # ID 0xFE status packets are fast replies: not stuffed
    if instr == dx2.STATUS and not params:
        params = b"\x00"
    raw = dx2.packet(dev_id, instr, params)
    p = dx2.Parser()
    got = p.feed(before + raw + after) + p.flush()
    assert any(g.id == dev_id and g.instr == instr and g.params == params and g.raw == raw
               for g in got)
    if _sdk_unstuffs_right(raw):   # the SDK's own removeStuffing agrees
        assert _sdk_params(raw) == params


def _sdk_params(raw: bytes) -> bytes:
    rx = PH.removeStuffing(list(raw))
    return bytes(rx[8:8 + (rx[5] | rx[6] << 8) - 3])


def _sdk_unstuffs_right(raw: bytes) -> bool:
    """Whether the SDK's removeStuffing reads only bytes it has not moved yet: it compacts
    in place but looks back at FF FF, so after its first removal a later FD FD may look
    stuffed (docs/protocol.md)."""
    end = 7 + (raw[5] | raw[6] << 8) - 2   # the positions it tests: INSTR up to the CRC
    pairs = [p for p in range(7, end) if raw[p] == raw[p + 1] == 0xFD]
    removals = [p for p in pairs if raw[p - 2] == raw[p - 1] == 0xFF]
    return not removals or all(p <= removals[0] for p in pairs)


def test_the_sdks_unstuffing_misreads_a_later_fd_fd_and_ours_does_not() -> None:
    params = b"\xff\xff\xfd\xff\xfd\xfd"
    raw = dx2.packet(254, dx2.PING, params)
    assert not _sdk_unstuffs_right(raw) and _sdk_params(raw) == params[:5]
    p = dx2.Parser()
    assert [g.params for g in p.feed(raw) + p.flush()] == [params]
    clean = dx2.packet(254, dx2.PING, b"\xff\xff\xfd\x01\xfd\x02")   # one pair: read right
    assert _sdk_unstuffs_right(clean) and _sdk_params(clean) == b"\xff\xff\xfd\x01\xfd\x02"


def test_stuffing_of_the_header_pattern() -> None:
    raw = dx2.write(1, 0, b"\xff\xff\xfd\xff")
    assert raw.hex() == "fffffd00010a00030000fffffdfdff6396"
    assert dx2.Parser().feed(raw)[0].params == b"\x00\x00\xff\xff\xfd\xff"


def test_bad_crc_is_rejected_and_the_next_packet_found() -> None:
    bad = bytearray(dx2.ping(3))
    bad[-1] ^= 1
    p = dx2.Parser()
    got = p.feed(bytes(bad) + dx2.ping(4))
    assert [g.id for g in got] == [4]
    assert p.bad_crc == 1 and p.last_bad_crc_id == 3


def test_fast_status_blocks_as_the_sdk_decodes_them() -> None:
    blocks = [(0, 1, b"\xa6\x00\x00\x00"), (dx2.ALERT, 2, b"\xff\xff\xfd\x00")]
    raw = dx2.fast_status(blocks)
    p = dx2.Parser()
    (pkt,) = p.feed(raw)
    assert pkt.id == dx2.BROADCAST_ID and pkt.raw == raw
    assert dx2.fast_blocks(pkt.params, [4, 4]) == blocks
    assert pkt.error == 0
    # each inner CRC is the running CRC of the packet up to it
    assert raw[14] | raw[15] << 8 == dx2.crc16(raw, 0, 14)


def test_timeout_drops_a_partial_packet() -> None:
    p = dx2.Parser()
    raw = dx2.ping(1)
    for b in raw[:5]:
        p.push(b, 0)
    assert not any(p.push(b, 200_000) for b in raw[5:])
    assert p.timeouts == 1


def test_error_names() -> None:
    assert dx2.error_names(dx2.ERR_ACCESS | dx2.ALERT) == ["access", "alert"]
    assert dx2.error_names(0) == []
