"""Property tests (hypothesis) of the Protocol 1.0 builders and the incremental parser."""
from __future__ import annotations

from hypothesis import assume, given, settings
from hypothesis import strategies as st

from hexhil.protocol.dynamixel import v1 as dxl

SETTINGS = settings(max_examples=200, deadline=None, derandomize=True)

ids = st.integers(0, dxl.MAX_ID)
any_id = st.integers(0, dxl.BROADCAST_ID)
address = st.integers(0, 255)
data = st.binary(min_size=1, max_size=60)


@st.composite
def instructions(draw: st.DrawFn) -> tuple[bytes, int, int, bytes]:
    """(packet, id, instruction, params) for each of the seven AX-12 instructions."""
    kind = draw(st.sampled_from(sorted(dxl.INSTRUCTION_NAMES)))
    if kind == dxl.PING:
        i = draw(ids)
        return dxl.ping(i), i, kind, b""
    if kind == dxl.READ:
        i, a, n = draw(ids), draw(address), draw(st.integers(1, 255))
        return dxl.read(i, a, n), i, kind, bytes((a, n))
    if kind in (dxl.WRITE, dxl.REG_WRITE):
        i, a, d = draw(any_id), draw(address), draw(data)
        build = dxl.write if kind == dxl.WRITE else dxl.reg_write
        return build(i, a, d), i, kind, bytes((a,)) + d
    if kind == dxl.ACTION:
        i = draw(any_id)
        return dxl.action(i), i, kind, b""
    if kind == dxl.FACTORY_RESET:
        i = draw(ids)
        return dxl.factory_reset(i), i, kind, b""
    n = draw(st.integers(1, 4))
    a = draw(address)
    entries = draw(st.lists(st.tuples(ids, st.binary(min_size=n, max_size=n)), min_size=1,
                            max_size=18, unique_by=lambda e: e[0]))
    params = bytes((a, n)) + b"".join(bytes((i,)) + d for i, d in entries)
    return dxl.sync_write(a, n, entries), dxl.BROADCAST_ID, kind, params


@st.composite
def statuses(draw: st.DrawFn) -> tuple[bytes, int, int, bytes]:
    i, err, params = draw(ids), draw(st.integers(0, 0x7F)), draw(st.binary(max_size=50))
    return dxl.status(i, err, params), i, err, params


packets = st.one_of(instructions(), statuses())


@SETTINGS
@given(packets)
def test_build_parse_round_trip(case: tuple[bytes, int, int, bytes]) -> None:
    pkt, dev_id, code, params = case
    assert pkt[3] == len(params) + 2 and len(pkt) == len(params) + 6
    out = dxl.Parser().feed(pkt)
    assert len(out) == 1
    assert (out[0].id, out[0].code, out[0].params, out[0].raw) == (dev_id, code, params, pkt)


@SETTINGS
@given(st.lists(packets, min_size=1, max_size=8))
def test_back_to_back_packets_all_parsed(cases: list) -> None:
    stream = b"".join(c[0] for c in cases)
    p = dxl.Parser()
    assert [q.raw for q in p.feed(stream)] == [c[0] for c in cases]
    assert p.garbage == p.bad_length == p.bad_checksum == 0


@SETTINGS
@given(st.binary(max_size=600))
def test_garbage_never_raises(junk: bytes) -> None:
    p = dxl.Parser()
    out = p.feed(junk) + p.flush()
    for q in out:  # whatever it finds is a well-formed packet found in the junk
        assert q.raw in junk and dxl.checksum(q.raw, 2, len(q.raw) - 1) == q.raw[-1]
    assert p.pending() == 0


@SETTINGS
@given(packets, st.data())
def test_truncation_never_yields_a_packet(case: tuple, draw: st.DataObject) -> None:
    pkt = case[0]
    cut = draw.draw(st.integers(0, len(pkt) - 1))
    p = dxl.Parser()
    assert p.feed(pkt[:cut]) == []
    assert p.pending() == cut  # everything held while it may still complete
    assert p.flush() == []


@SETTINGS
@given(packets, st.data())
def test_bit_flip_never_raises_and_checksum_catches_it(case: tuple, draw: st.DataObject) -> None:
    pkt = bytearray(case[0])
    pos = draw.draw(st.integers(0, len(pkt) - 1))
    pkt[pos] ^= 1 << draw.draw(st.integers(0, 7))
    p = dxl.Parser()
    out = p.feed(pkt) + p.flush()
    for q in out:
        assert dxl.checksum(q.raw, 2, len(q.raw) - 1) == q.raw[-1]
    if pos >= 4 or (pos == 2 and pkt[2] != 0xFF):  # framing intact: the checksum catches it
        assert out == [] and p.bad_checksum == 1


@SETTINGS
@given(st.binary(max_size=300), packets)
def test_valid_packet_after_garbage_is_recovered(junk: bytes, case: tuple) -> None:
    """The packet comes back, unless the junk's tail and the packet's head happen to form a
    packet with a valid checksum (then that one, which starts in the junk, is reported)."""
    pkt = case[0]
    p = dxl.Parser()
    out = p.feed(junk + pkt) + p.flush()
    raws = [q.raw for q in out]
    if pkt not in raws:
        stream = junk + pkt
        overlapping = [r for r in raws if any(stream.startswith(r, s) for s in
                                              range(max(0, len(junk) - len(r) + 1), len(junk)))]
        assert overlapping, (junk.hex(), pkt.hex(), [r.hex() for r in raws])
    assert p.pending() == 0


@SETTINGS
@given(st.binary(max_size=300).filter(lambda j: 0xFF not in j), packets)
def test_packet_after_garbage_without_ff_always_recovered(junk: bytes, case: tuple) -> None:
    p = dxl.Parser()
    out = p.feed(junk + case[0])  # no flush needed: the junk cannot start a header
    assert [q.raw for q in out] == [case[0]]
    assert p.garbage == len(junk)


@SETTINGS
@given(packets, st.integers(dxl.INTER_BYTE_TIMEOUT_US + 1, 10 ** 7), st.data())
def test_gap_over_100ms_drops_partial_then_recovers(case: tuple, gap_us: int,
                                                   draw: st.DataObject) -> None:
    pkt = case[0]
    cut = draw.draw(st.integers(1, len(pkt) - 1))
    p = dxl.Parser()
    t = 0
    for b in pkt[:cut]:
        assert not p.push(b, t)
        t += 10
    t += gap_us
    got = []
    for b in pkt:  # the servo hears the whole packet again after the gap
        if p.push(b, t):
            got.append(p.current().raw)
        t += 10
    got += [q.raw for q in p.flush()]
    assert p.timeouts == 1 and pkt in got


@SETTINGS
@given(st.lists(ids, min_size=1, max_size=30, unique=True), st.integers(1, 8), address)
def test_sync_write_rejects_wrong_entry_length(dev_ids: list[int], n: int, a: int) -> None:
    entries = [(i, bytes(n)) for i in dev_ids]
    assume(len(dev_ids) * (n + 1) + 4 <= 255)
    assert dxl.sync_write(a, n, entries)[3] == len(dev_ids) * (n + 1) + 4
    entries[-1] = (dev_ids[-1], bytes(n + 1))
    try:
        dxl.sync_write(a, n, entries)
    except ValueError as exc:
        assert "not %d" % n in str(exc)
    else:
        raise AssertionError("sync_write accepted an entry of the wrong length")
