"""Firmware tests written as pytest tests with the hexhil plugin (docs/testing.md).

    pytest examples/test_firmware_example.py --hexhil-runtime cpython-inprocess --junitxml out.xml

``hexhil_run`` runs a scenario with our firmware and returns the run (RunResult, summary, trace);
``run.check`` takes an expectation like an ``[[expect]]`` table and fails with the measured
value against the limit; ``assert_within`` does the same for any number. The last case runs
with the obstacle rule off, so its tactile check fails: it is marked xfail to keep this file
green; ``--runxfail`` shows the failure as a user would see it.
"""
from __future__ import annotations

from pathlib import Path

import pytest

import hexhil as hx
from hexhil.expect.pytest_plugin import assert_within

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
BOARD_TRIPOD = Path(__file__).resolve().parent / "board_tripod.py"   # a firmware of yours


@pytest.mark.parametrize("gait, speed_m_s", [("tripod", 0.036), ("wave", 0.013)])
def test_flat_walk_reaches_the_papers_speed(hexhil_run, gait: str, speed_m_s: float) -> None:
    run = hexhil_run(SCENARIOS / f"flat-{gait}.toml", duration_s=12)
    assert_within(f"{gait} speed", run.body["dx_m"] / 12, low=0.75 * speed_m_s, unit="m/s")
    run.check("protocol", name="no protocol violations")
    run.check("no_exception")


def test_your_firmware_walks(hexhil_run) -> None:
    """``firmware=`` (or ``--hexhil-firmware``) runs a firmware of yours instead of ours: a
    MicroPython main file on the virtual board, or an executable (docs/your-firmware.md)."""
    run = hexhil_run(SCENARIOS / "flat-tripod.toml", duration_s=8, firmware=BOARD_TRIPOD)
    assert run.summary["firmware_runtime"] == "micropython-board"
    run.check("displacement", window_s=(2, 8), dx_m=(0.15, 0.6))
    run.check("protocol")


@pytest.mark.parametrize("seed", [1, 2])
def test_heartbeat_reports_walking(hexhil_run, seed: int) -> None:
    run = hexhil_run(SCENARIOS / "flat-tripod.toml", seed=seed, duration_s=5)
    run.check("can", message="heartbeat", window_s=(1, 5), rate_hz=(9, 11),
              signals={"state": (2, 2)})
    # the typed result beside its --json view: the same run
    assert run.result.can_frames[hx.can_frames.ID_HEARTBEAT] >= 45
    assert run.result.serial_digest == run.summary["serial_digest"]


@pytest.mark.parametrize("tactile", [
    True, pytest.param(False, marks=pytest.mark.xfail(strict=True, reason="rule off"))])
def test_tactile_rule(hexhil_run, tactile: bool) -> None:
    run = hexhil_run(SCENARIOS / "obstacles-low-small.toml", duration_s=30, tactile=tactile)
    run.check("tactile_rule", name="tactile rule", min_steps=2)
