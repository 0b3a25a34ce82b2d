"""The world steps ahead while the firmware finishes its cycle (hil/run/lookahead.py): a run
with the lookahead is the run without it, byte for byte, whether its steps are kept (our
firmware) or taken back (a firmware off its rhythm), with faults and ground truth on the
way; and a world put back at its checkpoint steps on with the same bits."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hexhil.hil import scenario
from hexhil.hil.link.firmware_process import firmware_command
from hexhil.hil.run import lookahead
from hexhil.hil.run.lockstep import Simulator
from hexhil.hil.run.rig import make_world
from hexhil.hil.world.hexapod_world import HexapodWorld
from hexhil.trace import recorder as rec
from mpy import ROOT

OFF_RHYTHM = "tests/link_clients/firmware_off_rhythm.py"
SCENARIO = """
[scenario]
name = "lookahead"
seed = 5
duration_s = 2

[gait]
name = "tripod"

[world]
kind = "hexapod"
terrain = "obstacles"
density = "high"
height_class = "large"
length_m = 1.3

[faults]
unplug = [{ id = 5, at_s = 0.55, until_s = 0.9 }]   # plugged back: power-cycled, limp
brownout = [{ id = 2, at_s = 1.231 }]                 # off the cycles' grid: a leg goes limp
"""


def _run(tmp_path: Path, name: str, command: list[str], monkeypatch: pytest.MonkeyPatch,
         ahead: bool) -> tuple[str, bytes, list[lookahead.Lookahead]]:
    made: list[lookahead.Lookahead] = []
    init = lookahead.Lookahead.__init__

    def spy(self, *args):
        init(self, *args)
        made.append(self)

    with monkeypatch.context() as m:
        m.setattr(lookahead.Lookahead, "__init__", spy)
        if not ahead:
            m.setattr(HexapodWorld, "checkpoint", lambda self: None)
        path = tmp_path / "lookahead.toml"
        path.write_text(SCENARIO)
        out = tmp_path / f"{name}.mcap"
        sc = scenario.load_scenario(path)
        with rec.Recorder(out, {"scenario": "lookahead", "seed": 5}) as r:
            result = Simulator(sc, seed=5, world=make_world(sc, 5), recorder=r).run(
                duration_s=2.0, command=command)
    assert result.exit_code == 0 and result.cycles > 90
    return result.serial_digest, out.read_bytes(), made


@pytest.mark.parametrize("client", ["ours", "off rhythm"])
def test_a_run_with_the_lookahead_is_the_run_without_it(tmp_path, monkeypatch, client):
    command = firmware_command("micropython")
    if client == "off rhythm":
        command = command[:-2] + [OFF_RHYTHM]
    with_ahead = _run(tmp_path, "ahead", command, monkeypatch, True)
    without = _run(tmp_path, "plain", command, monkeypatch, False)
    assert with_ahead[:2] == without[:2]
    (ahead,) = with_ahead[2]
    assert ahead.kept > 50
    if client == "off rhythm":   # every 5th sleep early, every 7th batch with a write
        assert ahead.restored > 20
    else:
        assert ahead.restored <= 1   # the last batch: the firmware closing the link


def test_a_world_put_back_at_its_checkpoint_steps_on_with_the_same_bits():
    sc = scenario.load_scenario(ROOT / "scenarios" / "obstacles-high-large.toml")
    worlds = [make_world(sc, 0), make_world(sc, 0)]
    for w in worlds:
        w.drives.goal_rad += np.linspace(-0.5, 0.5, 18)
        w.advance_to(300_000)
    a, b = worlds
    saved, goal = a.checkpoint(), a.drives.goal_rad.copy()
    a.drives.goal_rad += 0.3      # steps ahead on other goals (a write the batch held)...
    a.advance_to(360_000)
    a.drives.goal_rad[:] = goal   # ...the goals are the bus's to set again, not the world's
    a.restore(saved)
    for w in worlds:
        w.advance_to(500_000)
    assert a.t_us == b.t_us and a.events == b.events and a.trajectory == b.trajectory
    for name in ("qpos", "qvel", "qacc_warmstart", "sensordata", "qfrc_actuator", "geom_xpos"):
        assert np.array_equal(getattr(a.data, name), getattr(b.data, name)), name
    assert np.array_equal(a.drives.setpoint_rad, b.drives.setpoint_rad)
    assert a.switches.state() == b.switches.state()
    assert list(a.scene_arrows()) == list(b.scene_arrows())
