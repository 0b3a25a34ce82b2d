"""hexhil replay: a recorded run replayed into the unchanged firmware reproduces its
outputs byte for byte (micropython and CPython); a changed firmware parameter is reported
as the first divergence; --can sends the logged frames through python-can."""
from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import can
import pytest

from hexhil.hil.run.lockstep import Simulator
from hexhil.hil import scenario
from hexhil import replay
from hexhil.cli import main
from hexhil.trace import protobuf as pb
from hexhil.trace import recorder as rec
from hexhil.trace import topics
from hexhil.trace.reader import open_trace

MICROPYTHON = str(Path(sys.executable).with_name("micropython"))
DURATION_S = 1.5


@pytest.fixture(scope="module")
def trace(tmp_path_factory):
    """A real lockstep run (firmware under micropython, 18 emulated servos) recorded."""
    path = tmp_path_factory.mktemp("replay") / "run.mcap"
    s = {section: {} for section in scenario.SCHEMA}
    with rec.Recorder(path, {"scenario": "defaults", "seed": 0}) as r:
        result = Simulator(s, seed=0, recorder=r).run(duration_s=DURATION_S,
                                                      python="micropython")
    assert result.exit_code == 0 and result.cycles > 50
    return path


def _cli(capsys, *argv):
    rc = main(list(argv))
    out, err = capsys.readouterr()
    return rc, json.loads(out.strip().splitlines()[-1]) if "--json" in argv else out, err


@pytest.mark.parametrize("python", ["micropython", "cpython"])
def test_unchanged_firmware_replays_identically(trace, capsys, python):
    rc, r, _ = _cli(capsys, "replay", str(trace), "--python", python, "--json")
    with open_trace(trace) as tr:
        n_link = sum(len(v["exchanges"]) for _, v in tr.decoded([topics.T_LINK]))
    assert rc == 0 and r["identical"] and r["first_divergence"] is None
    assert r["exchanges"] == n_link and r["compared_messages"] > n_link // 2


def test_end_and_rate_options(trace, capsys):
    rc, r, _ = _cli(capsys, "replay", str(trace), "--end", "0.5", "--rate", "50", "--json")
    assert rc == 0 and r["identical"]
    with open_trace(trace) as tr:
        times = [x["t_us"] for _, v in tr.decoded([topics.T_LINK]) for x in v["exchanges"]]
    n_half = sum(1 for t in times if t < 500_000)
    assert 0 < n_half < len(times)
    assert r["exchanges"] == n_half


def _changed_firmware(tmp_path, key, value):
    """The firmware with one default changed, started the way hil/link starts it."""
    script = tmp_path / "changed_firmware.py"
    script.write_text(f"from firmware import config\nconfig.DEFAULTS[{key!r}] = {value!r}\n"
                      "from firmware import main\nmain.main()\n")
    return [MICROPYTHON, str(script)]


def test_changed_parameter_reports_first_divergence(trace, tmp_path):
    cmd = _changed_firmware(tmp_path, "step_height_m", 0.031)
    r = replay.replay_firmware(trace, command=cmd)
    assert not r.identical
    d = r.divergence
    assert d.topic == "uart"  # the servo goal positions of the SYNC_WRITE change
    assert d.expected != d.actual and d.expected.startswith("W ")
    assert 0 <= d.t_s < DURATION_S
    # the exchange's servo-line bytes decoded in the trace's protocol (its scenario's model;
    # Protocol 1.0 here), the parameters against the AX-12's control table: the cycle's
    # SYNC_WRITE of 18 goals, then its three status READs (one R exchange on link
    # version 2, docs/link.md)
    assert d.packets is not None
    want, got = d.packets["expected"][0], d.packets["actual"][0]
    assert re.fullmatch(r"SYNC_WRITE Goal Position\+Moving Speed ids 1-18 "
                        r"\[1: \d+,\d+(; \d+: \d+,\d+){17}\]", want), want
    assert got.startswith("SYNC_WRITE Goal Position+Moving Speed ids 1-18 [") and got != want
    assert [p.split()[0] for p in d.packets["actual"]] == ["SYNC_WRITE", "READ", "READ", "READ"]
    assert re.fullmatch(r"READ id \d+ Present Position\+Present Speed\+Present Load \(36\) "
                        r"6 bytes", d.packets["actual"][1]), d.packets
    # the same firmware with the original value is identical again
    same = replay.replay_firmware(trace, command=_changed_firmware(tmp_path, "step_height_m",
                                                                   0.03))
    assert same.identical, same.divergence


def test_cli_exit_1_on_divergence(trace, tmp_path, capsys, monkeypatch):
    cmd = _changed_firmware(tmp_path, "step_height_m", 0.031)
    real = replay.FirmwareProcess
    monkeypatch.setattr(replay, "FirmwareProcess",
                        lambda python, **kw: real(python, **{**kw, "command": cmd}))
    rc, out, _ = _cli(capsys, "replay", str(trace))
    assert rc == 1 and "DIVERGED at t=" in out and "expected W " in out
    assert "expected packets: SYNC_WRITE Goal Position+Moving Speed ids 1-18 [1: " in out
    # a step-height change moves the servos but not the CAN or event outputs of 1.5 s:
    # --topics leaves the servo line out, so this replay passes
    rc, r, _ = _cli(capsys, "replay", str(trace), "--topics", "can,event", "--json")
    assert rc == 0 and r["identical"] and r["compared_messages"] > 0
    with open_trace(trace) as tr:
        n_can = sum(1 for f in (pb.CanFrame.FromString(m.data)
                                for m in tr.messages([topics.T_CAN_RAW])) if f.direction == "tx")
    assert r["compared_messages"] >= n_can


def test_a_start_past_the_traces_end_is_bad_input_not_identical(trace, capsys):
    rc, out, err = _cli(capsys, "replay", str(trace), "--start", "1000")
    assert rc == 2 and "identical" not in out
    assert err.startswith("hexhil: --start 1000: ") and "nothing to compare" in err


def test_unknown_replay_topic(trace, capsys):
    rc, _, err = _cli(capsys, "replay", str(trace), "--topics", "uart,bogus")
    assert rc == 2 and "bogus" in err


def test_a_link_topic_of_another_schema_is_one_line_exit_2(tmp_path, capsys):
    """A trace from before /link held one message a window (hexhil.LinkExchange each)."""
    from mcap.writer import Writer

    path = tmp_path / "old.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema("hexhil.LinkExchange", "protobuf", b"")
        cid = w.register_channel(topics.T_LINK, "protobuf", sid)
        w.add_message(cid, 0, b"\x12\x03abc", 0)
        w.finish()
    rc, _, err = _cli(capsys, "replay", str(path))
    assert rc == 2 and err.count("\n") == 1
    assert "hexhil.LinkExchange, not hexhil.LinkExchanges" in err


def test_replay_onto_can_sends_every_frame_in_order(trace):
    with open_trace(trace) as tr:
        want = [(f.arbitration_id, f.data) for f in
                (pb.CanFrame.FromString(m.data) for m in tr.messages([topics.T_CAN_RAW]))]
    assert want
    rx = can.Bus(interface="virtual", channel="replay-test")
    tx = can.Bus(interface="virtual", channel="replay-test")
    try:
        r = replay.replay_can(trace, "virtual:replay-test", rate=0, bus=tx)
        got = []
        while (m := rx.recv(timeout=0)) is not None:
            got.append((m.arbitration_id, bytes(m.data)))
    finally:
        rx.shutdown()
        tx.shutdown()
    assert r["frames"] == len(want) and got == want


def test_a_trace_of_cpython_in_process_replays_under_micropython(tmp_path, capsys):
    """MicroPython writes a JSON event's keys in another order than CPython; replay compares
    those events decoded, so a sweep's trace (firmware in process) replays under the
    reference runtime."""
    from hexhil.in_process import run_firmware

    def switches(t_us):   # LF pressed from 0.3 s to 0.4 s: two edges, tactile events
        return 1 if 300_000 <= t_us < 400_000 else 0

    path = tmp_path / "inproc.mcap"
    s = {section: {} for section in scenario.SCHEMA}
    with rec.Recorder(path, {"scenario": "defaults", "seed": 0}) as r:
        result = Simulator(s, seed=0, recorder=r, switches=switches).run(
            duration_s=DURATION_S, in_process=run_firmware)
    assert len(result.tactile_events) >= 2
    rc, out, _ = _cli(capsys, "replay", str(path), "--json")
    assert rc == 0 and out["identical"], out["first_divergence"]


def test_json_events_compare_decoded_and_still_catch_a_changed_value():
    from hexhil.protocol import sim_link

    def event(text):
        return (sim_link.OP_EVENT, bytes([sim_link.EVENT_TACTILE]) + text)

    assert replay._same(event(b'{"switch": 1, "leg": "LF"}'), event(b'{"leg": "LF", "switch": 1}'))
    assert not replay._same(event(b'{"switch": 1, "leg": "LF"}'), event(b'{"leg": "RF", "switch": 1}'))
    log = (sim_link.OP_EVENT, bytes([sim_link.EVENT_LOG]) + b'{"a": 1, "b": 2}')
    assert not replay._same(log, (sim_link.OP_EVENT, bytes([sim_link.EVENT_LOG]) + b'{"b": 2, "a": 1}'))
