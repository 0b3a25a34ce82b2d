"""Ctrl-C during a beams run (seed 000) ends it as it ends a hexapod run:
exit 130, one line naming the virtual time and the trace kept, the ``--json`` summary with
``"interrupted": true``, and a finished trace; at any moment of ``Run.run``, set-up included."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from ctrl_c import sigint_default
from hexhil.hil.run_result import RunInterrupted
from hexhil import run_summary
from hexhil.lockstep_run import Run
from hexhil.papers.beam_traversal import beams_run
from hexhil.trace.reader import Trace, info
from hexhil.trace.target import partial_of
from conftest import ROOT, hexhil_in_process as hexhil

FLIMSY = str(ROOT / "scenarios" / "beams-flimsy.toml")
KILL_AT_S = 1.0          # after the plan (0.43 s), before the far side (2.49 s)


def test_ctrl_c_during_a_beams_run_prints_the_line_and_the_summary_and_keeps_the_trace(
        tmp_path: Path) -> None:
    out = tmp_path / "beams.mcap"
    proc = subprocess.run([sys.executable, str(ROOT / "tests" / "kill_child.py"),
                           str(int(KILL_AT_S * 1e6)), str(int(signal.SIGINT)), "0", "run",
                           FLIMSY, "--json", "--out", str(out)], cwd=ROOT,
                          capture_output=True, text=True, timeout=300,
                          env=dict(os.environ, KILL_ON="clock"), preexec_fn=sigint_default)
    assert proc.returncode == 130, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert lines == [f"hexhil: interrupted at t={KILL_AT_S:.3f} s: the trace {out} is kept"], \
        proc.stderr                  # a beams trace holds no firmware link: nothing to replay
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    assert summary["interrupted"] is True and summary["world"] == "beams"
    assert summary["sim_time_s"] == pytest.approx(KILL_AT_S, abs=1e-3)
    assert not partial_of(out).exists()
    assert KILL_AT_S - 0.5 <= info(out)["end_s"] <= KILL_AT_S   # finished up to the stop
    cat = hexhil("trace", "cat", str(out), "--topics", "/can/body_pose")
    assert cat.returncode == 0 and cat.stdout.count("\n") >= 5, cat.stderr


def test_ctrl_c_before_the_traversal_loop_is_a_run_interrupted_with_the_trace_kept(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The plug-in's set-up (the simulator's construction) runs inside ``Run.run`` with the
    trace already open: Ctrl-C there is the same ``RunInterrupted``."""
    def pressed(*_args: object) -> None:
        raise KeyboardInterrupt
    monkeypatch.setattr(beams_run, "run_scenario", pressed)
    out = tmp_path / "early.mcap"
    with pytest.raises(RunInterrupted) as exc:
        Run(FLIMSY, trace=out).run()
    assert exc.value.result.interrupted and exc.value.result.runtime == "none"
    with Trace(out) as t:            # opens only a finished file (its summary)
        assert t.metadata()["scenario"].endswith("beams-flimsy.toml")
    with pytest.raises(RunInterrupted) as exc:
        run_summary.run(FLIMSY, out=str(tmp_path / "again.mcap"))
    assert exc.value.summary["interrupted"] is True and exc.value.summary["world"] == "beams"


def test_ctrl_c_in_a_c_extensions_import_is_exit_130_without_a_traceback(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """Ctrl-C while MuJoCo's extension initialises surfaces as ``ImportError:
    initialization failed`` (seen once in a beams run's first second); the plug-in's imports
    now run before the trace opens, and the CLI reads the Ctrl-C under the ImportError."""
    def importing(*_args: object) -> None:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise ImportError("initialization failed")
    monkeypatch.setattr(beams_run, "run_scenario", importing)
    from hexhil import cli

    assert cli.main(["run", str(FLIMSY)]) == 130
    assert "Traceback" not in capsys.readouterr().err
    broken = ImportError("no module named nothing")
    monkeypatch.setattr(beams_run, "run_scenario", lambda *_a: (_ for _ in ()).throw(broken))
    with pytest.raises(ImportError):    # an ImportError of its own stays one
        cli.main(["run", str(FLIMSY)])
