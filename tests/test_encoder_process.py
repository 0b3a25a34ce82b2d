"""Where the recorder encodes (host_tools/trace/windows.py): its child process
(encoder_process.py) writes the same bytes as the run's own process, flushes and discards
through it, says a full disk in the same one line and holds no descriptor of the run; in
the run's process, a closed window is written at the next idle(), and the simulator's wait
is worked in slices until the firmware answers."""
from __future__ import annotations

import os
import select

import pytest

from hexhil.trace import recorder as rec
from hexhil.trace.target import partial_of
from hexhil.protocol.dynamixel import v1 as dynamixel
from conftest import ROOT


def test_a_run_encoded_in_a_child_process_is_the_same_file(tmp_path):
    """The default child process writes the bytes the run's own process would."""
    from hexhil.hil import scenario
    from hexhil.hil.run.lockstep import Simulator
    from hexhil.hil.run.rig import make_world
    from hexhil.in_process import run_firmware

    sc = scenario.load_scenario(ROOT / "scenarios" / "obstacles-low-small.toml")
    for where in rec.EncodeIn:
        with rec.Recorder(tmp_path / f"{where.value}.mcap", {"seed": 3},
                          encode_in=where) as r:
            Simulator(sc, 3, world=make_world(sc, 3), recorder=r).run(
                1.2, in_process=run_firmware)
    assert ((tmp_path / "child-process.mcap").read_bytes()
            == (tmp_path / "this-process.mcap").read_bytes())


def test_an_idle_owner_gets_a_closed_window_written_in_its_idle_slices(tmp_path):
    """idle() takes a closed window's work (encoding, packing its chunk, writing it) off
    the call that closes the window, a slice at a time; one window waits at most, so the
    next window's close writes it if idle() has not (crash safety: the last two windows
    at most, as before)."""
    path = partial_of(tmp_path / "w.mcap")   # the file being written, renamed at close
    r = rec.Recorder(tmp_path / "w.mcap", flush_interval_us=100_000,
                     encode_in=rec.EncodeIn.THIS_PROCESS)
    r.serial(0, "tx", dynamixel.ping(1))
    r.idle(0)
    size = path.stat().st_size
    r.serial(100_000, "tx", dynamixel.ping(2))  # closes the first window
    assert path.stat().st_size == size
    slices = 1
    while r.idle(1):
        slices += 1
    assert path.stat().st_size > size and slices > 2
    size = path.stat().st_size
    r.serial(200_000, "tx", dynamixel.ping(3))  # closes the second: it waits
    r.idle(0)
    assert path.stat().st_size == size
    r.serial(300_000, "tx", dynamixel.ping(4))  # closes the third: the second is written
    assert path.stat().st_size > size
    r.close()


def test_flush_puts_the_held_messages_in_the_file_from_a_child_too(tmp_path):
    path = partial_of(tmp_path / "f.mcap")
    r = rec.Recorder(tmp_path / "f.mcap")
    size = path.stat().st_size
    r.serial(0, "tx", dynamixel.ping(1))
    r.flush()
    assert path.stat().st_size > size and r.messages == 1
    r.close()
    assert r.messages == 1 and (tmp_path / "f.mcap").exists()


def test_the_encoding_child_holds_no_descriptor_of_the_run_but_the_trace(tmp_path):
    """A firmware's socket or a pty the run closes must reach its peer's end of file, not
    stay open in the recorder's child."""
    read_end, write_end = os.pipe()
    r = rec.Recorder(tmp_path / "d.mcap")
    try:
        os.close(write_end)
        assert select.select([read_end], [], [], 10.0)[0] and os.read(read_end, 1) == b""
    finally:
        os.close(read_end)
        r.close()


def test_a_child_that_died_is_an_error_at_the_next_window_not_a_hang(tmp_path):
    import signal

    r = rec.Recorder(tmp_path / "k.mcap")
    os.kill(r._encoder.pid, signal.SIGKILL)
    r.serial(0, "tx", dynamixel.ping(1))
    with pytest.raises(RuntimeError, match="ended unexpectedly"):
        for t_us in (600_000, 1_200_000):   # the second waits for the first's report
            r.advance(t_us)
    assert r.closed
    r.close()   # nothing left to do
    assert partial_of(tmp_path / "k.mcap").exists()


def test_discard_stops_the_child_and_leaves_no_file(tmp_path):
    r = rec.Recorder(tmp_path / "x.mcap")
    r.serial(0, "tx", dynamixel.ping(1))
    r.advance(600_000)   # a window handed over
    r.discard()
    assert list(tmp_path.iterdir()) == []


FULL_DISK = """
import resource, sys
from hexhil.trace.recorder import EncodeIn, Recorder
from hexhil.protocol.errors import UserError
resource.setrlimit(resource.RLIMIT_FSIZE, (6000, 6000))
r = Recorder(sys.argv[1], encode_in=EncodeIn(sys.argv[2]))
try:
    for i in range(20000):
        r.telemetry(i * 1000, {"i": i, "pad": "x" * 40})
    r.close()
except UserError as exc:
    print(exc)
    sys.exit(2)
"""


def test_a_full_disk_in_the_child_is_the_runs_one_line(tmp_path):
    """The child cannot write: the run learns it at its next window and says the line the
    run's own process would, keeping what was written."""
    import subprocess
    import sys

    from hexhil.trace import recover

    lines = []
    for where in rec.EncodeIn:
        path = tmp_path / where.value / "full.mcap"
        path.parent.mkdir()
        proc = subprocess.run([sys.executable, "-c", FULL_DISK, str(path), where.value],
                              cwd=ROOT, capture_output=True, text=True, timeout=120,
                              env=dict(os.environ, PYTHONPATH=str(ROOT)))
        assert proc.returncode == 2, proc.stderr
        assert "Traceback" not in proc.stderr and proc.stdout.count("\n") == 1
        assert "cannot write trace" in proc.stdout
        assert recover.recover(path, path.with_name("rec.mcap"))["messages"] > 0
        lines.append(proc.stdout.replace(where.value, "WHERE"))
    assert lines[0] == lines[1]


@pytest.mark.parametrize("runtime,where", [("micropython", "this-process"),
                                          ("cpython", "this-process"),
                                          ("cpython-inprocess", "child-process")])
def test_a_run_encodes_beside_its_firmware_or_in_a_child(tmp_path, monkeypatch, runtime,
                                                        where):
    """A firmware in a process of its own leaves the run waiting while it computes, so the
    run encodes then; a firmware in the run's process leaves it nothing to wait on."""
    from hexhil.hil.link import cores
    from hexhil import Run

    monkeypatch.setattr(cores, "usable", lambda: 2.0)

    with Run(ROOT / "scenarios" / "flat-tripod.toml", runtime=runtime, duration_s=0.1,
             trace=tmp_path / "r.mcap") as run:
        assert run.recorder.encode_in.value == where


def test_with_one_cpu_the_encoding_stays_in_the_run(tmp_path, monkeypatch):
    """A child would take the run's only CPU (``taskset -c 0``, a cgroup quota of one)."""
    from hexhil.hil.link import cores
    from hexhil import Run

    monkeypatch.setattr(cores, "usable", lambda: 1.0)
    with Run(ROOT / "scenarios" / "flat-tripod.toml", runtime="cpython-inprocess",
             duration_s=0.1, trace=tmp_path / "r.mcap") as run:
        assert run.recorder.encode_in is rec.EncodeIn.THIS_PROCESS


def test_work_while_encodes_until_the_firmware_answers_or_nothing_is_left(tmp_path):
    r = rec.Recorder(tmp_path / "run.mcap", {"seed": 1}, encode_in=rec.EncodeIn.THIS_PROCESS)
    for t in range(0, 40_000, 1000):
        r.telemetry(t, {"t_us": t})
    looks = []

    def waiting() -> bool:   # the firmware answers at the third look
        looks.append(1)
        return len(looks) < 3
    r.work_while(waiting)
    assert len(looks) == 3 and r.idle(0)   # stopped at the answer, work left
    r.work_while(lambda: True)             # a long wait: returns once nothing is left
    assert not r.idle(0)
    r.close()
