"""The in-process firmware runtime: the same firmware under this CPython, linked
by function calls instead of a socket, must give micropython's bytes and results."""
import json
import subprocess
import sys
from dataclasses import replace

import pytest

from hexhil.hil.link.firmware_process import IN_PROCESS
from hexhil.hil.run.rig import make_world
from hexhil.hil.scenario import SCHEMA, load_scenario
from hexhil.hil.run.lockstep import Simulator
from hexhil.papers.tactile_hexapod import experiment as th
from hexhil.in_process import run_firmware
from hexhil.firmware import main as firmware_main
from hexhil.hil.run_result import RunInterrupted

from mpy import ROOT


def _bare(**sections):
    sc = {s: {} for s in SCHEMA}
    sc["_path"] = "<test>"
    sc.update(sections)
    return sc


def test_same_serial_digest_as_micropython_with_bit_errors():
    sc = _bare(gait={"name": "tripod"}, faults={"bit_error_rate": 1e-4})
    ref = Simulator(sc, seed=4).run(1.5, python="micropython")
    a = Simulator(sc, seed=4).run(1.5, in_process=run_firmware)
    b = Simulator(sc, seed=4).run(1.5, in_process=run_firmware)   # nothing left over
    assert ref.faults["bit_error"] > 0
    assert a.runtime == IN_PROCESS and a.exit_code == 0 and not a.exceptions
    assert a.serial_digest == b.serial_digest == ref.serial_digest
    assert a.round_trips == ref.round_trips and a.cycles == ref.cycles
    assert a.faults == ref.faults


def test_same_walk_over_obstacles_as_micropython():
    sc = load_scenario(ROOT / "scenarios" / "obstacles-high-large.toml")
    ref = Simulator(sc, 3, world=make_world(sc, 3)).run(6.0, python="micropython")
    got = Simulator(sc, 3, world=make_world(sc, 3)).run(6.0, in_process=run_firmware)
    assert got.serial_digest == ref.serial_digest
    assert got.switch_edges == ref.switch_edges > 0
    assert got.tactile_events == ref.tactile_events
    assert got.can_frames == ref.can_frames
    assert got.body == ref.body
    same = replace(got.firmware, compute_us_mean=ref.firmware.compute_us_mean,
                   compute_us_max=ref.firmware.compute_us_max)
    assert same == ref.firmware and ref.firmware.cycles > 0


def test_an_experiment_run_is_the_same_under_either_runtime():
    spec = th.RunSpec("calibration", "tripod", 1.0, True, 0, periods=2)
    ref = th.run_one(replace(spec, python="micropython"))
    got = th.run_one(spec)
    assert got["python"] == IN_PROCESS
    for key in ("wall_s", "python"):
        ref.pop(key), got.pop(key)
    assert got == ref and ref["x_m"] > 0.05


def test_hexhil_run_takes_the_in_process_runtime():
    def digest(python):
        out = subprocess.run([sys.executable, "-m", "hexhil.cli", "run",
                              "scenarios/flat-tripod.toml", "--duration", "2", "--json",
                              "--python", python], cwd=ROOT, capture_output=True, text=True)
        assert out.returncode == 0, out.stderr
        return json.loads(out.stdout.strip().splitlines()[-1])["serial_digest"]

    assert digest(IN_PROCESS) == digest("micropython")


def test_a_host_side_error_is_raised_not_reported_as_the_firmwares():
    class Broken:
        period_us = 100_000

        def tick(self, t_us):
            if t_us >= 300_000:
                raise ZeroDivisionError("a host node's bug")

    sc = _bare(gait={"name": "tripod"})
    sim = Simulator(sc, seed=1)
    sim.add_node(Broken())
    with pytest.raises(ZeroDivisionError, match="a host node's bug"):
        sim.run(1.0, in_process=run_firmware)
    # the firmware wound down; the next run in this process is whole
    again = Simulator(sc, seed=1).run(1.0, in_process=run_firmware)
    assert not again.exceptions and again.sim_time_s == 1.0
    assert again.serial_digest == Simulator(sc, seed=1).run(1.0, python="micropython").serial_digest



def _cleanup_fails_after(first):
    """A firmware whose ``finally`` raises on what ``first`` left half done."""
    def main(board):
        try:
            first(board)
        finally:
            raise ValueError("the clean-up's own error")
    return main


def _ctrl_c(board):
    raise KeyboardInterrupt


def _run(main, ctrl_c_at_call=None):
    """A 1 s run of ``main`` in process; the simulator raises a Ctrl-C at that link call."""
    calls = [0]

    def firmware(exchange):
        def interrupted(data, closed):
            calls[0] += 1
            if calls[0] == ctrl_c_at_call:
                raise KeyboardInterrupt   # the signal came while the simulator answered
            return exchange(data, closed)
        run_firmware(interrupted, main)
    return Simulator(_bare(gait={"name": "tripod"}), seed=1).run(1.0, in_process=firmware)


def test_a_ctrl_c_in_the_firmware_stays_a_ctrl_c_when_its_clean_up_fails():
    with pytest.raises(RunInterrupted):
        _run(_cleanup_fails_after(_ctrl_c))


def test_the_simulators_ctrl_c_is_raised_when_the_clean_up_fails_on_the_dead_link():
    with pytest.raises(RunInterrupted):
        _run(_cleanup_fails_after(firmware_main.main), ctrl_c_at_call=5)


@pytest.mark.parametrize("at_call", [1, 2, 30])   # the hello, the first cycle, a later one
def test_our_firmware_ends_on_a_ctrl_c_at_any_link_call(at_call):
    with pytest.raises(RunInterrupted):
        _run(firmware_main.main, ctrl_c_at_call=at_call)


def test_the_firmwares_own_error_is_raised_as_it_is():
    with pytest.raises(ValueError, match="the clean-up's own error"):
        _run(_cleanup_fails_after(lambda board: None))
