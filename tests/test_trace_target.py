"""A recorded trace is never lost: every trace is written to
``TARGET.partial`` and renamed at the end (host_tools/trace/target.py); an existing file is
refused unless ``--overwrite``; a second run onto the same target is refused while the
first holds it; a killed run's partial file is found by ``trace recover``; a full or
unwritable disk is one line."""
from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from ctrl_c import sigint_default
from hexhil.trace.reader import Trace, info
from hexhil.trace.recorder import Recorder
from hexhil.trace.target import partial_of
from hexhil.protocol.errors import UserError
from conftest import ROOT, hexhil, hexhil_in_process

FLAT = str(ROOT / "scenarios" / "flat-tripod.toml")
FAST = ("--python", "cpython-inprocess")


def one_line(r: subprocess.CompletedProcess) -> str:
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    return lines[0]


@pytest.fixture
def precious(tmp_path: Path) -> Path:
    out = tmp_path / "precious.mcap"
    r = hexhil_in_process("run", FLAT, "--duration", "1", *FAST, "--out", str(out))
    assert r.returncode == 0, r.stderr
    return out


def test_an_existing_trace_survives_out_onto_it(tmp_path: Path, precious: Path) -> None:
    before = precious.read_bytes()
    bad = tmp_path / "syntaxerr.py"
    bad.write_text("def (:\n")
    r = hexhil_in_process("run", FLAT, "--firmware", str(bad), "--out", str(precious))
    assert "precious.mcap exists: pass --overwrite" in one_line(r)
    r = hexhil_in_process("run", FLAT, "--duration", "0.5", *FAST, "--out", str(precious))
    assert "exists: pass --overwrite" in one_line(r)
    assert precious.read_bytes() == before and not partial_of(precious).exists()
    r = hexhil_in_process("run", FLAT, "--duration", "0.5", *FAST, "--out", str(precious),
                          "--overwrite")
    assert r.returncode == 0, r.stderr
    assert info(precious)["end_s"] == pytest.approx(0.5, abs=0.01)


def test_a_second_run_onto_one_target_is_refused_while_the_first_writes(tmp_path: Path
                                                                        ) -> None:
    out = tmp_path / "shared.mcap"
    first = subprocess.Popen([sys.executable, "-m", "hexhil.cli", "run", FLAT,
                              "--duration", "600", *FAST, "--out", str(out)], cwd=ROOT,
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                             preexec_fn=sigint_default)
    try:
        deadline = time.monotonic() + 120
        while not partial_of(out).exists() or partial_of(out).stat().st_size < 10_000:
            assert time.monotonic() < deadline and first.poll() is None
            time.sleep(0.1)
        # a process of its own, as a second user's run is: the first records on meanwhile
        r = hexhil("run", FLAT, "--duration", "1", *FAST, "--out", str(out), "--overwrite")
        assert "another run is writing this trace now" in one_line(r)
    finally:
        first.send_signal(signal.SIGINT)   # Ctrl-C: the first run finishes its file
        _, err = first.communicate(timeout=60)
    assert first.returncode == 130, err
    assert info(out)["end_s"] > 1.0 and not partial_of(out).exists()


def test_a_killed_run_leaves_its_partial_file_for_recover(tmp_path: Path) -> None:
    out = tmp_path / "killed.mcap"
    proc = subprocess.Popen([sys.executable, "-m", "hexhil.cli", "run", FLAT,
                             "--duration", "600", *FAST, "--out", str(out)], cwd=ROOT,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    while not partial_of(out).exists() or partial_of(out).stat().st_size < 50_000:
        assert time.monotonic() < deadline and proc.poll() is None
        time.sleep(0.1)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert not out.exists() and partial_of(out).exists()
    r = hexhil_in_process("trace", "info", str(out))
    assert "killed.mcap.partial beside it is the unfinished trace" in one_line(r)
    # a new run onto the target does not write over the killed run's partial file
    r = hexhil_in_process("run", FLAT, "--duration", "0.5", *FAST, "--out", str(out))
    assert "the unfinished trace of a run that was killed" in one_line(r)
    r = hexhil_in_process("trace", "recover", str(out), str(tmp_path / "rec.mcap"))
    assert r.returncode == 0, r.stderr
    assert info(tmp_path / "rec.mcap")["end_s"] > 0.4


@pytest.mark.parametrize("out,says", [
    ("/dev/full", "/dev/full: cannot write trace (No space left on device)"),
    ("/nonexistent-dir/t.mcap", "cannot write trace (No such file or directory)")])
def test_a_full_or_unwritable_disk_is_one_line(out: str, says: str) -> None:
    r = hexhil_in_process("run", FLAT, "--duration", "1", *FAST, "--out", out)
    assert says in one_line(r)


def test_the_api_refuses_an_existing_file_and_writes_a_partial_first(tmp_path: Path) -> None:
    path = tmp_path / "t.mcap"
    with Recorder(path, {"seed": 0}) as rec:
        rec.telemetry(0, {"x": 1})
        assert partial_of(path).exists() and not path.exists()
    assert path.exists() and not partial_of(path).exists()
    with pytest.raises(UserError, match="exists: pass overwrite"):
        Recorder(path)
    with Recorder(path, overwrite=True) as rec:
        rec.telemetry(0, {"x": 2})
    with Trace(path) as t:
        assert [m.data for m in t.messages()] == [b'{"x": 2}']


def test_kept_traces_are_not_overwritten_without_overwrite(tmp_path: Path) -> None:
    case = tmp_path / "c.toml"
    case.write_text(f'[case]\nscenario = "{FLAT}"\nduration_s = 1\n\n[[expect]]\n'
                    'name = "impossible"\nkind = "displacement"\ndx_m = [5, 6]\n')
    kept = tmp_path / "kept"
    argv = ("test", str(case), "--quiet", *FAST, "--keep-traces", str(kept))
    assert hexhil_in_process(*argv).returncode == 1
    before = (kept / "c.mcap").read_bytes()
    assert "kept/c.mcap exists: pass --overwrite" in one_line(hexhil_in_process(*argv))
    assert (kept / "c.mcap").read_bytes() == before
    assert hexhil_in_process(*argv, "--overwrite").returncode == 1
