"""``hexhil protocol decode``: hex in, packets out; malformed input is one line and exit 2."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from hexhil.cli import main
from hexhil.protocol.dynamixel import v1 as dxl

SYNC_4 = "FF FF FE 18 83 1E 04 00 10 00 50 01 01 20 02 60 03 02 30 00 70 01 03 20 02 80 03 12"


def run_json(capsys: pytest.CaptureFixture, *args: str) -> list[dict]:
    assert main(["protocol", "decode", "--json", *args]) == 0
    out = capsys.readouterr().out.splitlines()
    return [json.loads(line) for line in out]


def test_spaces_or_not_one_or_several_args_same_result(capsys: pytest.CaptureFixture) -> None:
    a = run_json(capsys, "FF FF 01 02 01 FB")
    b = run_json(capsys, "ffff010201fb")
    c = run_json(capsys, "FF", "FF", "01", "02", "01", "FB")
    d = run_json(capsys, "0xFF,0xFF,0x01,0x02,0x01,0xFB")
    assert a == b == c == d
    assert a[0] == {"id": 1, "kind": "instruction", "instruction": "PING", "params": [],
                    "raw": "ffff010201fb", "offset": 0}
    assert a[-1] == {"kind": "summary", "packets": 1, "garbage_bytes": 0, "bytes": 6}


def test_ping_and_read_exchanges_from_the_manual(capsys: pytest.CaptureFixture) -> None:
    recs = run_json(capsys, "FF FF 01 02 01 FB", "FF FF 01 02 00 FC",
                    "FF FF 01 04 02 2B 01 CC FF FF 01 03 00 20 DB")
    assert [(r["kind"], r.get("instruction"), r.get("error")) for r in recs[:-1]] == [
        ("instruction", "PING", None), ("status", None, []),
        ("instruction", "READ", None), ("status", None, [])]
    assert recs[2]["address"] == 43 and recs[2]["length"] == 1
    assert recs[2]["register"] == "present_temperature"
    assert recs[3]["params"] == [0x20] and recs[3]["reply_to"] == "READ"


def test_sync_write_entries(capsys: pytest.CaptureFixture) -> None:
    (rec, summary) = run_json(capsys, SYNC_4)
    assert rec["instruction"] == "SYNC_WRITE" and rec["id"] == 0xFE
    assert (rec["address"], rec["length"]) == (30, 4)
    assert rec["entries"] == [{"id": 0, "data": [0x10, 0x00, 0x50, 0x01]},
                              {"id": 1, "data": [0x20, 0x02, 0x60, 0x03]},
                              {"id": 2, "data": [0x30, 0x00, 0x70, 0x01]},
                              {"id": 3, "data": [0x20, 0x02, 0x80, 0x03]}]
    assert summary["packets"] == 1


def test_every_instruction_decodes_by_name(capsys: pytest.CaptureFixture) -> None:
    pkts = [dxl.ping(3), dxl.read(3, 36, 2), dxl.write(4, 30, b"\x00\x02"),
            dxl.reg_write(5, 24, b"\x01"), dxl.action(), dxl.factory_reset(6),
            dxl.sync_write(30, 2, [(1, b"\x00\x02"), (2, b"\xff\x03")])]
    recs = run_json(capsys, *(p.hex() for p in pkts))[:-1]
    assert [r["instruction"] for r in recs] == ["PING", "READ", "WRITE", "REG_WRITE", "ACTION",
                                                "FACTORY_RESET", "SYNC_WRITE"]
    assert recs[2]["data"] == [0, 2] and recs[2]["register"] == "goal_position"
    assert recs[3]["register"] == "torque_enable"


def test_kind_rule_and_flags(capsys: pytest.CaptureFixture) -> None:
    # code 0x01 after a PING to another id is an instruction (a PING), not an error byte
    recs = run_json(capsys, dxl.ping(1).hex(), dxl.packet(2, 0x01).hex())
    assert [r["kind"] for r in recs[:2]] == ["instruction", "instruction"]
    # ... but from the id just pinged it is the reply, with the input-voltage bit set
    recs = run_json(capsys, dxl.ping(1).hex(), dxl.packet(1, 0x01).hex())
    assert recs[1]["kind"] == "status" and recs[1]["error"] == ["input_voltage"]
    # the SDK's ping (PING then READ of the model number) seen without replies: the READ
    # has parameters, which a PING's reply never has
    recs = run_json(capsys, dxl.ping(1).hex(), dxl.read(1, 0, 2).hex(),
                    dxl.status(1, 0, b"\x0c\x00").hex())
    assert [r["kind"] for r in recs[:3]] == ["instruction", "instruction", "status"]
    assert recs[2]["reply_to"] == "READ" and recs[2]["register"] == "model_number"
    # a broadcast gets no reply, so the packet after it is read on its own
    recs = run_json(capsys, dxl.action().hex(), dxl.packet(0xFE, 0x05).hex())
    assert [r["kind"] for r in recs[:2]] == ["instruction", "instruction"]
    # a code that is no instruction is a status packet's error byte
    recs = run_json(capsys, "FF FF 01 02 24 D8")
    assert recs[0]["kind"] == "status" and recs[0]["error"] == ["overheating", "overload"]
    recs = run_json(capsys, "--status", "FF FF 01 02 01 FB")
    assert recs[0]["kind"] == "status" and recs[0]["error"] == ["input_voltage"]
    recs = run_json(capsys, "--instruction", "FF FF 01 02 00 FC")
    assert recs[0]["instruction"] == "UNKNOWN_0x00"


def test_garbage_is_reported_not_fatal(capsys: pytest.CaptureFixture) -> None:
    recs = run_json(capsys, "12 34", "FF FF 01 02 01 FB", "00 FF", "FF FF 01 02 00 FC", "AA")
    kinds = [(r["kind"], r.get("offset")) for r in recs]
    assert kinds == [("garbage", 0), ("instruction", 2), ("garbage", 8), ("status", 10),
                     ("garbage", 16), ("summary", None)]
    assert recs[0]["bytes"] == [0x12, 0x34] and recs[2]["bytes"] == [0x00, 0xFF]
    assert recs[-1] == {"kind": "summary", "packets": 2, "garbage_bytes": 5, "bytes": 17}


def test_text_output(capsys: pytest.CaptureFixture) -> None:
    assert main(["protocol", "decode", "00", SYNC_4]) == 0
    out = capsys.readouterr().out
    assert "garbage: 1 bytes: 00" in out
    assert "SYNC_WRITE address=30 (goal_position) length=4 to 4 ids" in out
    assert "id   3: 20 02 80 03" in out
    assert out.splitlines()[-1] == "1 packets, 1 garbage bytes, 29 bytes"


@pytest.mark.parametrize("args, why", [
    (["FF FF 01 02 01 F"], "odd number of hex digits (11)"),
    (["FF", "FF", "01", "02", "01", "FBX"], "not hex: 'X' in 'FBX' (argument 6)"),
    (["FF FF 01 02 01 FA"], "bad checksum at byte 0 (id 1): 0xFA, expected 0xFB"),
    (["FF FF 01 02 01 FB FF FF 01 04 02 2B 01"], "truncated packet at byte 6 (id 1): LEN 4"),
    (["00 FF FF 01"], "truncated packet at byte 1: 3 bytes"),
    (["FF FF 01 01 01 FC"], "bad length at byte 0: LEN 1"),
    (["12 34 56"], "no Dynamixel packet in 3 bytes"),
    (["FF FF 07 F0 FF FF 01 02 01 FB"], "LEN 240 runs into the packet at byte 4"),
    ([dxl.packet(0xFE, dxl.SYNC_WRITE, b"\x1e\x04\x01\x02").hex()], "bad SYNC_WRITE"),
])
def test_malformed_input_one_line_exit_2(capsys: pytest.CaptureFixture, args: list[str],
                                         why: str) -> None:
    assert main(["protocol", "decode", *args]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.count("\n") == 1 and why in captured.err, captured.err


def test_lenient_turns_bad_packets_into_reported_garbage(capsys: pytest.CaptureFixture) -> None:
    recs = run_json(capsys, "--lenient", "FF FF 01 02 01 FA FF FF 01 02 01 FB")
    assert recs[0]["kind"] == "garbage" and "bad checksum" in recs[0]["reason"]
    assert recs[1]["instruction"] == "PING" and recs[1]["offset"] == 6


def test_console_script_no_traceback() -> None:
    """The installed entry point: one line on stderr, exit 2, for each kind of bad input."""
    exe = [sys.executable, "-m", "hexhil.cli", "protocol", "decode"]
    for bad in (["FFF"], ["FF FF 01 02 01 FA"], ["FF FF 01 02"]):
        r = subprocess.run(exe + bad, capture_output=True, text=True, timeout=60)
        assert r.returncode == 2 and r.stdout == ""
        assert len(r.stderr.splitlines()) == 1 and r.stderr.startswith("hexhil: ")
    r = subprocess.run(exe + ["--json", "ffff010201fb"], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 0 and json.loads(r.stdout.splitlines()[-1])["kind"] == "summary"


def test_protocol_2_bytes_are_recognised_and_unstuffed(capsys: pytest.CaptureFixture) -> None:
    from hexhil.protocol.dynamixel import v2 as dx2

    data = b"\x00" + dx2.sync_read(132, 4, [1, 2]) + dx2.status(1, dx2.ERR_ACCESS | dx2.ALERT,
                                                                b"\xff\xff\xfd\x00")
    recs = run_json(capsys, data.hex())
    assert [r["kind"] for r in recs] == ["garbage", "instruction", "status", "summary"]
    assert recs[1]["instruction"] == "SYNC_READ" and recs[1]["ids"] == [1, 2]
    assert recs[1]["register"] == "present_position"
    assert recs[2]["params"] == [0xFF, 0xFF, 0xFD, 0] and recs[2]["error"] == ["access", "alert"]
    assert recs[3]["protocol"] == 2 and recs[3]["packets"] == 2


def test_packets_in_words_read_against_the_models_control_table() -> None:
    """What a replay divergence prints (host_tools/dynamixel/decode/words.py), built on the
    decoder ``hexhil protocol decode`` uses: Protocol 1.0 against the AX-12's table, 2.0
    against the XL430's, a status packet's error bits and data."""
    from hexhil.dynamixel.decode import DECODERS
    from hexhil.protocol.dynamixel import v2 as dx2

    v1, v2 = DECODERS[1].names, DECODERS[2].names
    le = int.to_bytes
    assert v1(dxl.write(3, 30, le(512, 2, "little"))) == ["WRITE id 3 Goal Position (30) = 512"]
    assert v1(dxl.sync_write(30, 4, [(i, le(500 + i, 2, "little") + le(100, 2, "little"))
                                     for i in (1, 2, 3, 7)])) == [
        "SYNC_WRITE Goal Position+Moving Speed ids 1-3,7 "
        "[1: 501,100; 2: 502,100; 3: 503,100; 7: 507,100]"]
    assert v1(dxl.read(5, 36, 2) + dxl.status(5, 0, le(512, 2, "little"))) == [
        "READ id 5 Present Position (36) 2 bytes", "status id 5 ok: Present Position (36) = 512"]
    assert v1(dxl.status(5, dxl.ERR_OVERLOAD | dxl.ERR_ANGLE_LIMIT, b"\x01")) == [
        "status id 5 angle_limit,overload: data 01"]
    assert v1(dxl.write(4, 31, b"\x01")) == ["WRITE id 4 address 31 = 01"]   # mid-field
    assert v2(dx2.write(3, 116, le(2048, 4, "little"))) == [
        "WRITE id 3 Goal Position (116) = 2048"]
    assert v2(dx2.sync_write(116, 4, [(1, le(-5, 4, "little", signed=True))])) == [
        "SYNC_WRITE Goal Position ids 1 [1: -5]"]
    assert v2(dx2.read(5, 132, 4) + dx2.status(5, dx2.ALERT | dx2.ERR_DATA_LIMIT,
                                                  le(2048, 4, "little"))) == [
        "READ id 5 Present Position (132) 4 bytes", "status id 5 data_limit,alert: data 00 08 00 00"]
    assert v2(dx2.bulk_read([(1, 132, 4), (2, 126, 2)])) == [
        "BULK_READ id 1 Present Position (132) 4 bytes; id 2 Present Load (126) 2 bytes"]
    assert v2(dx2.ping(7)) == ["PING id 7"]


@pytest.mark.parametrize("protocol", [1, 2])
def test_a_packet_inside_a_rejected_headers_length_keeps_its_own_offset(
        capsys: pytest.CaptureFixture, protocol: int) -> None:
    """A garbage header whose LEN spans a real packet: the parser finds that packet only when
    the LEN is complete, with the bytes after it still held; the decoder places it where it
    lay and the filler after it is garbage (what the coverage-guided parser target found)."""
    from hexhil.dynamixel.decode import packet_spans
    from hexhil.protocol.dynamixel import v2 as dx2

    codec = dx2 if protocol == 2 else dxl
    bogus = b"\xff\xff\xfd\x00\x01\x14\x00" if protocol == 2 else b"\xff\xff\x01\x10"
    first, second = codec.ping(1), codec.ping(2)
    data = bogus + first + bytes(12) + second
    at_second = len(bogus) + len(first) + 12
    assert packet_spans(data, protocol) == [(len(bogus), len(first), False),
                                             (at_second, len(second), False)]
    recs = run_json(capsys, "--lenient", data.hex())
    assert [(r["kind"], r.get("offset")) for r in recs[:-1]] == [
        ("garbage", 0), ("instruction", len(bogus)), ("garbage", len(bogus) + len(first)),
        ("instruction", at_second)]
    assert recs[2]["bytes"] == [0] * 12 and bytes.fromhex(recs[1]["raw"]) == first
