"""Golden vectors: every example packet of the ROBOTIS e-manual "Protocol 1.0" page
(ROBOTIS-GIT/emanual, docs/en/dxl/protocol1.md) and the AX-12 manual's 4-servo SYNC_WRITE.

Each vector is checked both ways: our builder produces the manual's bytes, and our parser
reads the manual's bytes back to the same fields.
"""
from __future__ import annotations

import pytest

from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl


def h(text: str) -> bytes:
    return bytes.fromhex(text)


# (what, bytes from the manual, our builder's output, id, code, params)
VECTORS = [
    ("checksum example: WRITE id 1, params 0C 64 AA", h("FF FF 01 05 03 0C 64 AA DC"),
     dxl.write(1, 0x0C, b"\x64\xAA"), 1, dxl.WRITE, [0x0C, 0x64, 0xAA]),
    ("status with overload + overheating", h("FF FF 01 02 24 D8"),
     dxl.status(1, dxl.ERR_OVERLOAD | dxl.ERR_OVERHEATING), 1, 0x24, []),
    ("PING id 1", h("FF FF 01 02 01 FB"), dxl.ping(1), 1, dxl.PING, []),
    ("PING reply", h("FF FF 01 02 00 FC"), dxl.status(1), 1, 0, []),
    ("READ present temperature (43) of id 1", h("FF FF 01 04 02 2B 01 CC"),
     dxl.read(1, ax12.PRESENT_TEMPERATURE, 1), 1, dxl.READ, [0x2B, 0x01]),
    ("READ reply: 32 degC", h("FF FF 01 03 00 20 DB"), dxl.status(1, 0, b"\x20"), 1, 0, [0x20]),
    ("WRITE id 1 to the ID register, broadcast", h("FF FF FE 04 03 03 01 F6"),
     dxl.write(dxl.BROADCAST_ID, ax12.ID, b"\x01"), 0xFE, dxl.WRITE, [0x03, 0x01]),
    ("REG_WRITE goal position 500 to id 1", h("FF FF 01 05 04 1E F4 01 E2"),
     dxl.reg_write(1, ax12.GOAL_POSITION, (500).to_bytes(2, "little")), 1, dxl.REG_WRITE,
     [0x1E, 0xF4, 0x01]),
    ("REG_WRITE reply", h("FF FF 01 02 00 FC"), dxl.status(1), 1, 0, []),
    ("ACTION, broadcast", h("FF FF FE 02 05 FA"), dxl.action(), 0xFE, dxl.ACTION, []),
    ("FACTORY_RESET id 0", h("FF FF 00 02 06 F7"), dxl.factory_reset(0), 0, dxl.FACTORY_RESET, []),
    ("FACTORY_RESET reply", h("FF FF 00 02 00 FD"), dxl.status(0), 0, 0, []),
    ("SYNC_WRITE position+speed to ids 0, 1 (e-manual)",
     h("FF FF FE 0E 83 1E 04 00 10 00 50 01 01 20 02 60 03 67"),
     dxl.sync_write(ax12.GOAL_POSITION, 4, [(0, h("10 00 50 01")), (1, h("20 02 60 03"))]),
     0xFE, dxl.SYNC_WRITE, list(h("1E 04 00 10 00 50 01 01 20 02 60 03"))),
    ("SYNC_WRITE position+speed to ids 0-3 (AX-12 manual)",
     h("FF FF FE 18 83 1E 04 00 10 00 50 01 01 20 02 60 03 02 30 00 70 01 03 20 02 80 03 12"),
     dxl.sync_write(ax12.GOAL_POSITION, 4, [(0, h("10 00 50 01")), (1, h("20 02 60 03")),
                                            (2, h("30 00 70 01")), (3, h("20 02 80 03"))]),
     0xFE, dxl.SYNC_WRITE,
     list(h("1E 04 00 10 00 50 01 01 20 02 60 03 02 30 00 70 01 03 20 02 80 03"))),
]


@pytest.mark.parametrize("what, manual, built, dev_id, code, params", VECTORS,
                         ids=[v[0] for v in VECTORS])
def test_builder_matches_manual(what: str, manual: bytes, built: bytes, dev_id: int, code: int,
                                params: list[int]) -> None:
    assert built == manual


@pytest.mark.parametrize("what, manual, built, dev_id, code, params", VECTORS,
                         ids=[v[0] for v in VECTORS])
def test_parser_reads_manual(what: str, manual: bytes, built: bytes, dev_id: int, code: int,
                             params: list[int]) -> None:
    p = dxl.Parser()
    hits = [i for i, b in enumerate(manual) if p.push(b, i * 10)]
    assert hits == [len(manual) - 1], "exactly one packet, complete at its last byte"
    assert (p.id, p.code, p.nparams) == (dev_id, code, len(params))
    assert [p.param(i) for i in range(p.nparams)] == params
    assert p.counters() == {"packets": 1, "garbage": 0, "bad_length": 0, "bad_checksum": 0,
                            "timeouts": 0}


def test_manual_checksum_arithmetic() -> None:
    """The e-manual's worked example: ~(0x01+0x05+0x03+0x0C+0x64+0xAA) = ~0x123 -> 0xDC."""
    pkt = h("FF FF 01 05 03 0C 64 AA DC")
    assert sum(pkt[2:-1]) == 0x123
    assert dxl.checksum(pkt, 2, len(pkt) - 1) == 0xDC


def test_sync_write_4_servo_checksum_by_hand() -> None:
    """The AX-12 manual's SYNC_WRITE ends in 0x12: the byte sum is 0x3ED, ~0xED & 0xFF = 0x12."""
    pkt = VECTORS[-1][1]
    assert len(pkt) == 28 and pkt[3] == len(pkt) - 4 == (4 + 1) * 4 + 4  # LEN = (L+1)N + 4
    assert sum(pkt[2:-1]) == 0x3ED and (~0x3ED) & 0xFF == 0x12 == pkt[-1]


def test_status_error_names_of_manual_example() -> None:
    """FF FF 01 02 24 D8: "Bit5 and Bit2 become 1 ... Overload and Overheating"."""
    assert dxl.error_names(0x24) == ["overheating", "overload"]
    assert dxl.error_names(0x7F) == ["input_voltage", "angle_limit", "overheating", "range",
                                     "checksum", "overload", "instruction"]


@pytest.mark.parametrize("bad, reason", [
    (h("FF FF 01 02 01 FA"), "bad_checksum"),
    (h("FF FF 01 01 01 FB"), "bad_length"),
])
def test_manual_packet_corrupted_is_rejected_and_counted(bad: bytes, reason: str) -> None:
    p = dxl.Parser()
    assert p.feed(bad) == [] and p.flush() == []
    assert p.last_reject == reason and p.counters()[reason] >= 1


def test_inter_byte_timeout_drops_partial_packet() -> None:
    """A gap over 100 ms between bytes drops the partial packet (the next one still parses)."""
    p = dxl.Parser()
    ping = h("FF FF 01 02 01 FB")
    for b in ping[:3]:
        assert not p.push(b, 0)
    assert not p.push(ping[3], dxl.INTER_BYTE_TIMEOUT_US + 1)
    assert p.timeouts == 1
    # exactly 100 ms is still in time
    q = dxl.Parser()
    got = [q.push(b, i * dxl.INTER_BYTE_TIMEOUT_US) for i, b in enumerate(ping)]
    assert got[-1] and q.timeouts == 0
    assert [pkt.raw for pkt in p.feed(ping, 10 ** 6)] == [ping]
