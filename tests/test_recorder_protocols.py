"""The recorder decodes /serial in the line's own protocol (host_tools/dynamixel/decode/):
a Protocol 2.0 trace carries its packets like a 1.0 trace (instruction, id, parameters,
errors) in the same schema; `trace cat`, export and replay's divergences read them."""
from __future__ import annotations

import json
import re
import sys
from pathlib import Path

from hexhil import lockstep_run, replay
from hexhil.dynamixel.decode import DECODERS
from hexhil.cli import main
from hexhil.trace import reader as trace_reader
from hexhil.trace import recorder as rec
from hexhil.trace import topics
from hexhil.protocol.dynamixel import v1 as dx1
from hexhil.protocol.dynamixel import v2 as dx2

MICROPYTHON = str(Path(sys.executable).with_name("micropython"))


def _packets(path) -> list[dict]:
    with trace_reader.open_trace(path) as tr:
        return [dict(p, direction=v["direction"]) for _, v in tr.decoded([topics.T_SERIAL])
                for p in v["packets"]]


def test_a_protocol_2_burst_split_anywhere_is_decoded_in_the_1_0_schema(tmp_path) -> None:
    sync = dx2.sync_write(116, 4, [(1, (2100).to_bytes(4, "little")), (2, bytes(4))])
    read = dx2.sync_read(132, 4, [1, 2])
    status = dx2.status(2, dx2.ALERT | dx2.ERR_DATA_LIMIT, (0xFDFFFF).to_bytes(4, "little"))
    with rec.Recorder(tmp_path / "v2.mcap", protocol=2) as r:
        r.serial(1000, "tx", sync[:5])
        r.serial(1100, "tx", sync[5:] + read)
        r.serial(1500, "rx", b"\x00" + status[:9])       # a garbage byte first
        r.serial(1600, "rx", status[9:])
    got = _packets(tmp_path / "v2.mcap")
    assert [(p["direction"], p["instruction"], p["id"]) for p in got] == [
        ("tx", "SYNC_WRITE", 254), ("tx", "SYNC_READ", 254), ("rx", "", 2)]
    assert bytes.fromhex(got[0]["params"]) == sync[8:-2] and got[0]["code"] == dx2.SYNC_WRITE
    # a status packet as in Protocol 1.0: its error byte is the code, its names the errors,
    # its parameters the data after it (unstuffed), its raw the bytes on the wire
    assert got[2]["code"] == dx2.ALERT | dx2.ERR_DATA_LIMIT
    assert got[2]["errors"] == "data_limit,alert"
    assert bytes.fromhex(got[2]["params"]) == (0xFDFFFF).to_bytes(4, "little")
    assert bytes.fromhex(got[2]["raw"]) == status
    with rec.Recorder(tmp_path / "v1.mcap") as r:     # the same fields, Protocol 1.0
        r.serial(1000, "tx", dx1.sync_write(30, 2, [(1, b"\x00\x02")]))
    assert set(_packets(tmp_path / "v1.mcap")[0]) == set(got[0])


def test_an_xl430_run_trace_names_its_sync_writes_and_sync_reads(tmp_path, capsys) -> None:
    out = tmp_path / "xl430.mcap"
    scenario = {"scenario": {"name": "xl430-kinematic", "duration_s": 0.4},
                "bus": {"model": "xl430-w250"}, "gait": {"name": "tripod"}}
    lockstep_run.Run(scenario, runtime="cpython-inprocess", trace=out).run()
    names = {(p["direction"], p["instruction"]) for p in _packets(out)}
    assert {("tx", "PING"), ("tx", "SYNC_WRITE"), ("tx", "SYNC_READ"), ("rx", "")} <= names
    assert main(["trace", "cat", str(out), "--topics", "/serial"]) == 0
    assert '"instruction": "SYNC_READ"' in capsys.readouterr().out
    with trace_reader.open_trace(out) as tr:      # replay decodes its divergences so
        assert replay.trace_model(tr) == "xl430-w250"
    assert DECODERS[2].names(dx2.sync_read(132, 4, [1, 2]) + dx2.status(1, 0, bytes(4))) == [
        "SYNC_READ Present Position (132) 4 bytes ids 1-2", "status id 1 ok: data 00 00 00 00"]
    csv = tmp_path / "serial.csv"
    assert main(["trace", "export", str(out), str(csv), "--topics", "/serial"]) == 0
    assert "SYNC_WRITE" in csv.read_text() and "SYNC_READ" in csv.read_text()


def test_a_protocol_2_replay_divergence_names_the_parameters(tmp_path) -> None:
    """An XL430 run replayed into our firmware with one default changed: the diverging
    SYNC_WRITE is read against the XL430's control table (Protocol 2.0)."""
    out = tmp_path / "xl430.mcap"
    scenario = {"scenario": {"name": "xl430-kinematic", "duration_s": 1.0},
                "bus": {"model": "xl430-w250"}, "gait": {"name": "tripod"}}
    lockstep_run.Run(scenario, runtime="micropython", trace=out).run()
    script = tmp_path / "changed_firmware.py"
    script.write_text("from firmware import config\nconfig.DEFAULTS['step_height_m'] = 0.031\n"
                      "from firmware import main\nmain.main()\n")
    r = replay.replay_firmware(out, command=[MICROPYTHON, str(script)])
    d = r.divergence
    assert d is not None and d.topic == "uart" and d.packets is not None, r
    want, got = d.packets["expected"][0], d.packets["actual"][0]
    head = "SYNC_WRITE Profile Velocity+Goal Position ids 1-18 ["    # addresses 112, 116
    assert re.fullmatch(re.escape(head) + r"1: \d+,-?\d+(; \d+: \d+,-?\d+){17}\]", want), want
    assert got.startswith(head) and got != want
