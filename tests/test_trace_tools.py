"""hexhil trace info|cat|export|recover|import-csv, estimate on imported data, and the
one-line exit-2 answer of every trace/replay/estimate command to bad input."""
from __future__ import annotations

import csv
import io
import json
import subprocess
import sys
from pathlib import Path

import can
import pytest
from mcap.records import Message
from mcap.stream_reader import StreamReader, breakup_chunk

from hexhil.trace import reader as trace_reader
from hexhil.trace import recorder as rec
from hexhil.trace import recover as trace_recover
from hexhil.cli import main
from hexhil.protocol import can_frames


def _trace(path, seconds: float = 2.0):
    """CAN at 100 Hz (force + body_pose + heartbeat) plus serial bytes."""
    r = rec.Recorder(path, {"seed": 3})
    frames = []
    for i in range(int(seconds * 100)):
        t = i * 10_000
        for name, sig in (("force", dict(fx_n=0.001 * i, fy_n=-0.5, fz_n=0.25, sample=i)),
                          ("heartbeat", dict(state=2, fault_flags=0, cycle=i, overruns=0))):
            arb, data = can_frames.encode(name, **sig)
            r.can(t, arb, data, direction="rx" if name == "force" else "tx")
            frames.append((t, arb, data))
        r.serial(t, "tx", bytes.fromhex("FFFF010201FB"))
    r.close()
    return frames


def _cli(capsys, *argv):
    rc = main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


def test_info_counts_topics_times(tmp_path, capsys):
    p = tmp_path / "t.mcap"
    _trace(p)
    rc, out, _ = _cli(capsys, "trace", "info", str(p), "--json")
    assert rc == 0
    s = json.loads(out.strip().splitlines()[-1])
    counts = {t["topic"]: t["messages"] for t in s["topics"]}
    assert counts == {"/can/raw": 400, "/can/force": 200, "/can/heartbeat": 200,
                      "/serial": 200}
    assert s["start_s"] == 0.0 and s["end_s"] == pytest.approx(1.99)
    assert s["duration_s"] == pytest.approx(1.99)
    assert s["metadata"]["seed"] == "3"
    rc, out, _ = _cli(capsys, "trace", "info", str(p))
    assert rc == 0 and "/can/force" in out and "duration:  1.990000 s" in out


def test_cat_filters_by_topic_glob_and_time(tmp_path, capsys):
    p = tmp_path / "t.mcap"
    _trace(p)
    rc, out, _ = _cli(capsys, "trace", "cat", str(p), "--topics", "/can/f*",
                      "--start", "0.5", "--end", "0.55")
    lines = out.strip().splitlines()
    assert rc == 0 and len(lines) == 5
    t, topic, body = lines[0].split(" ", 2)
    assert (t, topic) == ("0.500000", "/can/force")
    assert json.loads(body)["sample"] == 50 and json.loads(body)["fx_n"] == pytest.approx(0.05)
    rc, _, err = _cli(capsys, "trace", "cat", str(p), "--topics", "/nope")
    assert rc == 2 and "no topic matches /nope" in err


def test_export_csv_and_python_can_logs(tmp_path, capsys):
    p = tmp_path / "t.mcap"
    frames = _trace(p)
    out = tmp_path / "force.csv"
    assert _cli(capsys, "trace", "export", str(p), str(out), "--topics", "/can/force")[0] == 0
    rows = list(csv.DictReader(open(out)))
    assert len(rows) == 200 and float(rows[10]["fx_n"]) == pytest.approx(0.01)
    assert rows[10]["time_s"] == "0.100000"
    d = tmp_path / "all"
    assert _cli(capsys, "trace", "export", str(p), str(d))[0] == 0
    assert sorted(x.name for x in d.iterdir()) == ["can_force.csv", "can_heartbeat.csv",
                                                   "can_raw.csv", "serial.csv"]
    for suffix in (".asc", ".blf"):
        log = tmp_path / f"can{suffix}"
        assert _cli(capsys, "trace", "export", str(p), str(log))[0] == 0
        got = list(can.LogReader(str(log)))
        assert [(m.arbitration_id, bytes(m.data)) for m in got] == \
               [(a, d) for _, a, d in frames]
        assert [round(m.timestamp, 6) for m in got] == [t / 1e6 for t, _, _ in frames]
    rc, _, err = _cli(capsys, "trace", "export", str(p), str(tmp_path / "x.parquet"))
    assert rc == 2 and "unknown export format" in err


def test_recover_truncated_file(tmp_path, capsys):
    p = tmp_path / "t.mcap"
    _trace(p, seconds=3.0)
    data = p.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 2 // 3])
    rc, _, err = _cli(capsys, "trace", "info", str(cut))
    assert rc == 2 and "recover" in err and len(err.strip().splitlines()) == 1
    out = tmp_path / "rec.mcap"
    rc, o, _ = _cli(capsys, "trace", "recover", str(cut), str(out), "--json")
    r = json.loads(o.strip().splitlines()[-1])
    assert rc == 0 and r["messages"] > 0 and not r["complete"]
    # what came back is an exact prefix of the original, in time
    with trace_reader.open_trace(p) as a, trace_reader.open_trace(out) as b:
        full = [(m.topic, m.log_time_ns, m.data) for m in a.messages()]
        got = [(m.topic, m.log_time_ns, m.data) for m in b.messages()]
    assert sorted(got) == sorted(x for x in full if x[1] <= r["end_s"] * 1e9)
    # a complete file recovers completely
    rc, o, _ = _cli(capsys, "trace", "recover", str(p), str(tmp_path / "same.mcap"), "--json")
    r = json.loads(o.strip().splitlines()[-1])
    assert r["complete"] and r["messages"] == len(full)


def _beams_csv(path, k=(0.3, 0.5), hb_m=0.0, seconds=1.2):
    """A 100 Hz force + pose log of the seed-000 beams world, as a physical robot logs it."""
    from hexhil.hil.world.beam_body import BeamParams
    from hexhil.hil.world.beams import SENSOR_PERIOD_US, BeamsWorld

    w = BeamsWorld(beams=[BeamParams(k[0], hb_m), BeamParams(k[1], hb_m)])
    with open(path, "w", newline="") as f:
        out = csv.writer(f)
        out.writerow(["time_s", "fx_n", "fy_n", "fz_n", "x_m", "roll_rad", "pitch_rad", "tx_nm"])
        while w.t_us < seconds * 1e6:
            w.step()
            if w.t_us % SENSOR_PERIOD_US == 0:
                s = w.state
                out.writerow([w.t_us / 1e6, *w.sense_force(), s.x_m, s.roll_rad, s.pitch_rad, 0])


def test_import_csv_then_estimate_recovers_stiffness(tmp_path, capsys):
    src, mcap = tmp_path / "robot.csv", tmp_path / "robot.mcap"
    _beams_csv(src)
    rc, o, _ = _cli(capsys, "trace", "import-csv", str(src), str(mcap), "--json")
    r = json.loads(o.strip().splitlines()[-1])
    assert rc == 0 and r["samples"] == 120 and r["pose"] and r["ignored_columns"] == ["tx_nm"]
    topics = {t["topic"] for t in trace_reader.info(mcap)["topics"]}
    assert {"/can/force", "/can/body_pose", "/body"} <= topics
    rc, o, _ = _cli(capsys, "estimate", str(mcap), "--unknowns", "2", "--json")
    e = json.loads(o.strip().splitlines()[-1])
    assert rc == 0 and e["samples"] == 30  # T_s = 0.3 s at 100 Hz (Sec. II-E)
    # k comes back through 1 mN / 0.1 mrad CAN resolution within a few percent
    assert e["k1"] == pytest.approx(0.3, rel=0.05) and e["k2"] == pytest.approx(0.5, rel=0.05)


BAD_CSVS = {
    "missing column": "time_s,fx_n,fy_n\n0,1,2\n",
    "not a number": "time_s,fx_n,fy_n,fz_n\n0,a,2,3\n",
    "time goes back": "time_s,fx_n,fy_n,fz_n\n1,0,0,0\n0.5,0,0,0\n",
    "empty": "time_s,fx_n,fy_n,fz_n\n",
}


@pytest.mark.parametrize("why", sorted(BAD_CSVS))
def test_import_csv_bad_input_is_one_line(tmp_path, capsys, why):
    src = tmp_path / "bad.csv"
    src.write_text(BAD_CSVS[why])
    rc, _, err = _cli(capsys, "trace", "import-csv", str(src), str(tmp_path / "o.mcap"))
    assert rc == 2 and err.startswith("hexhil: ") and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o.mcap").exists()


def _bad_files(tmp_path):
    good = tmp_path / "good.mcap"
    _trace(good, seconds=3.0)
    data = good.read_bytes()
    files = {
        "missing": tmp_path / "missing.mcap",
        "empty": tmp_path / "empty.mcap",
        "not mcap": tmp_path / "text.mcap",
        "truncated": tmp_path / "trunc.mcap",
        "corrupt": tmp_path / "corrupt.mcap",
        "directory": tmp_path,
    }
    files["empty"].write_bytes(b"")
    files["not mcap"].write_text("time_s,fx_n\n0,1\n")
    files["truncated"].write_bytes(data[: len(data) // 2])
    # flip bytes inside the first chunk's compressed data: the chunk CRC catches it
    with trace_reader.open_trace(good) as tr:
        ci = min(tr.summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    bad = bytearray(data)
    for i in range(ci.chunk_start_offset + 80, ci.chunk_start_offset + 120):
        bad[i] ^= 0x5A
    files["corrupt"].write_bytes(bytes(bad))
    return files


COMMANDS = [
    ("trace", "info", "{f}"),
    ("trace", "cat", "{f}"),
    ("trace", "export", "{f}", "{tmp}/out.csv"),
    ("trace", "export", "{f}", "{tmp}/out.asc"),
    ("replay", "{f}"),
    ("replay", "{f}", "--can", "virtual:x"),
    ("estimate", "{f}"),
    ("grnn", "dataset", "--out", "{tmp}/ds", "{f}"),
]


@pytest.mark.parametrize("cmd", COMMANDS, ids=lambda c: " ".join(c[:2]))
def test_bad_trace_input_is_one_line_exit_2(tmp_path, capsys, cmd):
    for why, f in _bad_files(tmp_path).items():
        argv = [a.format(f=f, tmp=tmp_path) for a in cmd]
        rc, _, err = _cli(capsys, *argv)
        assert rc == 2, (why, argv, err)
        assert err.startswith("hexhil: ") and len(err.strip().splitlines()) == 1, (why, err)


def test_recover_bad_input(tmp_path, capsys):
    files = _bad_files(tmp_path)
    for why in ("missing", "empty", "not mcap", "directory"):
        rc, _, err = _cli(capsys, "trace", "recover", str(files[why]), str(tmp_path / "o.mcap"))
        assert rc == 2 and len(err.strip().splitlines()) == 1, (why, err)
    # a corrupt first chunk: recover skips just that chunk and says where
    rc, o, _ = _cli(capsys, "trace", "recover", str(files["corrupt"]), str(tmp_path / "o.mcap"),
                    "--json")
    r = json.loads(o.strip().splitlines()[-1])
    assert rc == 0 and not r["complete"] and r["messages"] > 0
    assert [d["why"] for d in r["damaged"]] == ["damaged"] and r["orphaned_messages"] == 0


def _messages(path):
    with trace_reader.open_trace(path) as tr:
        return sorted((m.topic, m.log_time_ns, m.data) for m in tr.messages())


def _chunks(path):
    """(start offset, end offset, its messages) of each chunk, in file order."""
    with trace_reader.open_trace(path) as tr:
        cis = sorted(tr.summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
        topic = {cid: ch.topic for cid, ch in tr.channels.items()}
    data = Path(path).read_bytes()
    out = []
    for ci in cis:
        end = ci.chunk_start_offset + ci.chunk_length
        chunk = next(StreamReader(io.BytesIO(data[ci.chunk_start_offset:end]), skip_magic=True,
                                  emit_chunks=True).records)
        msgs = [(topic[m.channel_id], m.log_time, m.data) for m in breakup_chunk(chunk)
                if isinstance(m, Message)]
        out.append((ci.chunk_start_offset, end, msgs))
    return out


@pytest.mark.parametrize("where", ["payload", "length field"])
def test_recover_skips_a_damaged_middle_chunk_and_keeps_the_rest(tmp_path, where):
    """A bad block in the middle of a finished file loses that chunk's messages only: the
    reader goes on at the next chunk that passes its CRC, even when the damage hit the
    chunk's length field so that its end cannot be known."""
    good = tmp_path / "good.mcap"
    _trace(good, seconds=4.0)
    chunks = _chunks(good)
    assert len(chunks) >= 4
    start, end, lost = chunks[len(chunks) // 2]
    bad = bytearray(good.read_bytes())
    at = range(start + 1, start + 9) if where == "length field" else range(start + 200, start + 260)
    for i in at:
        bad[i] ^= 0xA5
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(bytes(bad))
    r = trace_recover.recover(damaged, tmp_path / "rec.mcap")
    assert not r["complete"] and r["orphaned_messages"] == 0
    assert [(d["byte"], d["byte"] + d["bytes"], d["why"]) for d in r["damaged"]] == \
        [(start, chunks[len(chunks) // 2 + 1][0], "damaged")]
    assert r["damaged"][0]["after_s"] < min(t for _, t, _ in lost) / 1e9
    assert r["damaged"][0]["before_s"] > max(t for _, t, _ in lost) / 1e9
    full = _messages(good)
    assert _messages(tmp_path / "rec.mcap") == sorted(set(full) - set(lost)) and \
        len(full) - len(lost) == r["messages"]


def test_recover_a_crash_cut_file_with_a_damaged_chunk(tmp_path):
    """No summary to fall back on: the rest comes back up to the cut, and a channel whose
    record was in a damaged span loses its messages, counted as orphaned (with no CRC to
    tell a channel record from garbage, reading resumes only at a chunk)."""
    good = tmp_path / "good.mcap"
    _trace(good, seconds=4.0)
    chunks = _chunks(good)
    bad = bytearray(good.read_bytes()[:(chunks[-2][0] + chunks[-2][1]) // 2])  # cut mid-chunk
    for i in range(chunks[1][0] + 200, chunks[1][0] + 260):
        bad[i] ^= 0xA5
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(bytes(bad))
    r = trace_recover.recover(cut, tmp_path / "rec.mcap")
    assert [d["why"] for d in r["damaged"]] == ["damaged", "cut off"]
    assert r["stopped"] == f"cut off at byte {chunks[-2][0]}"
    kept = {m for _, _, msgs in chunks[:-2] for m in msgs} - set(chunks[1][2])
    assert _messages(tmp_path / "rec.mcap") == sorted(kept) and r["orphaned_messages"] == 0
    # now also the length field of the first channel record (top level, before any chunk)
    first_channel = bytes(bad).index(b"/can/", 8) - 1
    while bad[first_channel] != 0x04:  # back to the channel record's opcode
        first_channel -= 1
    for i in range(first_channel + 1, first_channel + 9):
        bad[i] ^= 0xA5
    cut.write_bytes(bytes(bad))
    r = trace_recover.recover(cut, tmp_path / "rec2.mcap")
    # reading resumes at the first chunk, but every channel record lay in the skipped span
    assert [(d["byte"], d["byte"] + d["bytes"]) for d in r["damaged"][:2]] == \
        [(first_channel, chunks[0][0]), (chunks[1][0], chunks[2][0])]
    assert r["messages"] == 0 and r["orphaned_messages"] == len(kept)


def test_no_traceback_from_the_real_command_line(tmp_path):
    bad = tmp_path / "trunc.mcap"
    bad.write_bytes(b"\x89MCAP0\r\n" + b"\x01" * 40)
    for argv in (["trace", "info", str(bad)], ["replay", str(bad)], ["estimate", str(bad)]):
        p = subprocess.run([sys.executable, "-m", "hexhil.cli", *argv], capture_output=True,
                           text=True)
        assert p.returncode == 2 and "Traceback" not in p.stderr
        assert len(p.stderr.strip().splitlines()) == 1


def test_fast_chunk_reader_matches_the_mcap_library(tmp_path):
    p = tmp_path / "t.mcap"
    _trace(p, seconds=3.0)
    with trace_reader.open_trace(p) as tr:
        assert tr.file_order_is_time_order
        for topics, start, end in ((None, None, None), (["/can/*"], 0.5, 1.25),
                                   (["/serial"], 2.0, None)):
            ours = [(m.topic, m.log_time_ns, m.data) for m in tr.messages(topics, start, end)]
            sel = tr.select_topics(topics)
            lib = [(c.topic, m.log_time, m.data) for _, c, m in tr.reader.iter_messages(
                topics=sel, log_time_order=True,
                starting_at=None if start is None else int(start * 1e9),
                ending_before=None if end is None else int(end * 1e9))]
            assert ours == lib and ours


def test_estimate_reproduces_the_estimate_a_beams_run_logged(tmp_path, capsys):
    """`hexhil beams run --out` logs force/pose frames and the estimate it made online;
    re-running the estimator on the logged frames gives that estimate back (to the
    beam_estimate frame's resolution: 2e-5 N m/rad, 0.02 mm)."""
    from hexhil.papers.beam_traversal.beams_run import RunConfig, run

    p = tmp_path / "beams.mcap"
    with rec.Recorder(p, {"command": "beams run"}) as r:
        out = run(RunConfig(0.3, 0.5, strategy="interact", fx_n=0.1, max_time_s=0.4), recorder=r)
    online = out["estimate"]
    rc, o, _ = _cli(capsys, "estimate", str(p), "--unknowns", "3", "--json")
    e = json.loads(o.strip().splitlines()[-1])
    assert rc == 0 and e["samples"] == out["force_samples"]
    assert e["k1"] == pytest.approx(online["k1"], abs=1e-9)
    assert e["k2"] == pytest.approx(online["k2"], abs=1e-9)
    logged = e["logged_estimate"]
    assert abs(logged["k1"] - e["k1"]) <= 2e-5 and abs(logged["k2"] - e["k2"]) <= 2e-5
    assert abs(logged["hb_mm"] - e["hb1_mm"]) <= 0.02 + 1e-9
