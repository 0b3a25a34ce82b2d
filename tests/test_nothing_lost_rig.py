"""Nothing recorded is lost, beyond ``hexhil run --out``: the real-time rig
(``hexhil bus --world ... --out``) driven by our firmware over a pty, and an experiment
recording every run (``hexhil experiment tactile-hexapod --traces``).

What is checked, and why no more: the rig runs against the wall clock, so two runs never
write the same bytes and there is no reference to compare with. ``tests/kill_child.py``
sends the signal at a known *virtual* time (the rig's clock starts at the master's first
byte), so after SIGKILL ``hexhil trace recover`` must give back messages up to at most 1 s
of virtual time before the kill, every one of them decoding; SIGTERM and Ctrl-C must end
the command cleanly (exit 0, no traceback) with a finished file that holds the run up to
the stop. An experiment's runs are deterministic, but a second unbroken sweep to compare
with would take minutes; its test checks that every trace finished before the kill reads
whole (summary and all) and that the one being written recovers to within 1 s of the kill.
"""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from ctrl_c import sigint_default
from hexhil.trace.reader import Trace
from hexhil.trace.recover import recover
from hexhil.trace.topics import T_BODY, T_SERIAL
from conftest import ROOT

KILL_CHILD = str(ROOT / "tests" / "kill_child.py")
MICROPYTHON = str(Path(sys.executable).with_name("micropython"))
LOSS_S = 1.0      # the bound; the recorder writes every 0.5 s of virtual time
STOP_GAP_S = 0.1  # a clean stop keeps the run to its last exchange before the signal


def _read_whole(path: Path) -> tuple[set[str], float, int]:
    """Topics, last log time (s) and message count; every message decodes."""
    with Trace(path) as t:
        topics, last, n = set(), 0.0, 0
        for m, _ in t.decoded():
            topics.add(m.topic)
            last = max(last, m.log_time_ns / 1e9)
            n += 1
    return topics, last, n


def _rig(out: Path, kill_at_s: float, signum: int) -> subprocess.CompletedProcess:
    """``hexhil bus --world flat-tripod --out`` with our firmware as the master, signalled
    at ``kill_at_s`` of the rig's virtual time."""
    proc = subprocess.Popen([sys.executable, KILL_CHILD, str(int(kill_at_s * 1e6)),
                             str(int(signum)), "0", "bus", "--world",
                             "scenarios/flat-tripod.toml", "--out", str(out), "--duration",
                             "10"], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, preexec_fn=sigint_default)
    line = proc.stdout.readline().strip()
    assert line.startswith("pty: "), (line, proc.stderr.read() if proc.poll() else "")
    env = dict(os.environ, MICROPYPATH=f"{ROOT}:.frozen")
    fw = subprocess.Popen([MICROPYTHON, "firmware/main.py", "--serial", line[5:]], cwd=ROOT,
                          env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        out_text, err = proc.communicate(timeout=60)
    finally:
        fw.kill()
        fw.wait(timeout=10)
    return subprocess.CompletedProcess(proc.args, proc.returncode, out_text, err)


@pytest.mark.parametrize("kill_at_s", [1.3, 2.8])
def test_bus_out_sigkill_loses_at_most_one_second(kill_at_s: float, tmp_path: Path) -> None:
    out = tmp_path / "rig.mcap"
    proc = _rig(out, kill_at_s, signal.SIGKILL)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    r = recover(out, tmp_path / "recovered.mcap")
    assert r["end_s"] >= kill_at_s - LOSS_S, r
    topics, last, n = _read_whole(tmp_path / "recovered.mcap")
    assert n == r["messages"] and {T_SERIAL, T_BODY} <= topics, topics
    assert last == pytest.approx(r["end_s"])


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_bus_out_sigterm_and_ctrl_c_finish_the_file(signum: int, tmp_path: Path) -> None:
    out = tmp_path / "rig.mcap"
    proc = _rig(out, 2.0, signum)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr and "served " in proc.stdout, proc.stderr
    topics, last, _ = _read_whole(out)  # Trace opens only a finished file (summary)
    assert {T_SERIAL, T_BODY} <= topics, topics
    assert 2.0 - STOP_GAP_S <= last < 2.0 + STOP_GAP_S, last


@pytest.mark.slow
def test_experiment_traces_survive_sigkill(tmp_path: Path) -> None:
    """SIGKILL 3 s into the second traced run of ``--quick --seeds 1 --workers 1`` (one
    process; half a minute or more: the probes and a whole 1 m walk come first)."""
    kill_at_s = 3.0
    proc = subprocess.run([sys.executable, KILL_CHILD, str(int(kill_at_s * 1e6)),
                           str(int(signal.SIGKILL)), "0", "experiment", "tactile-hexapod",
                           "--quick", "--seeds", "1", "--traces", "--workers", "1", "--out",
                           str(tmp_path / "exp")], cwd=ROOT, capture_output=True, text=True,
                          timeout=900, env=dict(os.environ, KILL_IN_RECORDING="2"))
    assert proc.returncode == -signal.SIGKILL, proc.stderr[-2000:]
    opened = [Path(p) for p in re.findall(r"recording (\S+\.mcap)", proc.stderr)]
    assert len(opened) == 2, proc.stderr[-2000:]
    finished, cut = opened
    topics, last, n = _read_whole(finished)
    assert n > 0 and {T_SERIAL, T_BODY} <= topics and last > kill_at_s
    r = recover(cut, tmp_path / "recovered.mcap")
    assert not r["complete"] and r["end_s"] >= kill_at_s - LOSS_S, r
    assert _read_whole(tmp_path / "recovered.mcap")[2] == r["messages"]
