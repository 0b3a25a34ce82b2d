"""Nothing recorded is lost: SIGKILL, SIGTERM and Ctrl-C at several simulated
moments of ``hexhil run --out``, and a full disk. After SIGKILL ``hexhil trace recover``
gives back every message up to 1 s before the kill, byte for byte as an unbroken run wrote
it; SIGTERM and SIGINT end with a finished file; a failed write gives one line and keeps
what was written."""
from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest

from ctrl_c import sigint_default
from hexhil.trace.reader import Trace
from hexhil.trace.recover import recover
from conftest import ROOT

SCENARIO = str(ROOT / "scenarios" / "flat-tripod.toml")
DURATION_S = 5.0
LOSS_S = 1.0  # the bound; the recorder writes every 0.5 s of virtual time


def _hexhil(out: Path, kill_at_s: float = 0.0, signum: int = 0, fsize: int = 0
            ) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(ROOT / "tests" / "kill_child.py"),
                           str(int(kill_at_s * 1e6)), str(int(signum)), str(fsize), "run",
                           SCENARIO, "--duration", str(DURATION_S), "--out", str(out)],
                          cwd=ROOT, capture_output=True, text=True, timeout=300,
                          preexec_fn=sigint_default)


def _messages(path: Path, before_s: float = 1e9) -> list[tuple[str, int, bytes]]:
    with Trace(path) as t:
        return [(m.topic, m.log_time_ns, m.data) for m in t.messages()
                if m.log_time_ns < before_s * 1e9]


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("ref") / "ref.mcap"
    proc = _hexhil(out)
    assert proc.returncode == 0, proc.stderr
    return out


@pytest.mark.parametrize("kill_at_s", [0.7, 2.3, 3.9])
def test_sigkill_loses_at_most_one_second(kill_at_s: float, reference: Path,
                                          tmp_path: Path) -> None:
    out = tmp_path / "killed.mcap"
    proc = _hexhil(out, kill_at_s, signal.SIGKILL)
    assert proc.returncode == -signal.SIGKILL
    r = recover(out, tmp_path / "recovered.mcap")
    assert r["end_s"] >= kill_at_s - LOSS_S, r
    got = _messages(tmp_path / "recovered.mcap")
    want = _messages(reference, kill_at_s - LOSS_S)
    assert got[:len(want)] == want
    assert got == _messages(reference)[:len(got)]  # nothing corrupt, nothing out of order


@pytest.mark.parametrize("signum,status", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_sigterm_and_ctrl_c_finish_the_file(signum: int, status: int, reference: Path,
                                            tmp_path: Path) -> None:
    out = tmp_path / "stopped.mcap"
    proc = _hexhil(out, 2.3, signum)
    assert proc.returncode == status, proc.stderr
    assert "Traceback" not in proc.stderr
    got = _messages(out)  # opens only with a summary: the file was finished
    want = _messages(reference, 2.3 - LOSS_S)
    assert got[:len(want)] == want


def test_a_full_disk_gives_one_line_and_keeps_what_was_written(reference: Path,
                                                               tmp_path: Path) -> None:
    out = tmp_path / "full.mcap"
    limit = reference.stat().st_size // 2
    proc = _hexhil(out, fsize=limit)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "cannot write trace" in lines[0], proc.stderr
    r = recover(out, tmp_path / "recovered.mcap")
    assert r["messages"] > 0
    got = _messages(tmp_path / "recovered.mcap")
    assert got == _messages(reference)[:len(got)]
