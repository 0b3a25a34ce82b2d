"""The navigator: a host node on the run's CAN bus that stops the walk
where it predicts the goal. It must see the same steps the dataset reads from the trace
(else the GRNN would be fed other features than it learned from), stop the firmware through
``gait_command``, and refuse bad options in one line."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from hexhil.hil import scenario as scenario_mod
from hexhil.cli import main as cli
from hexhil.papers.tactile_hexapod import experiment as th
from hexhil.papers.tactile_hexapod.grnn import data, navigator, train
from hexhil.papers.tactile_hexapod.grnn.dataset import rows_from_trace
from hexhil.trace.reader import Trace
from hexhil.trace.topics import T_BODY
from conftest import ROOT

PERIOD_S = 2.778
# A short walk to a goal over obstacles: 0.3 m is 3 tripod periods at the nominal speed, so
# the known path is the first 2 steps and the navigator decides from the third on.
SCENARIO = f"""
[scenario]
name = "short-goal"
seed = 4
duration_s = {6 * PERIOD_S}

[gait]
name = "tripod"
period_s = {PERIOD_S}
distance_m = 0.3
max_obstacle_height_m = 0.05

[firmware]
tactile = true

[world]
kind = "hexapod"
terrain = "obstacles"
density = "high"
height_class = "small"
length_m = 0.8
"""


@pytest.fixture(scope="module")
def short_goal(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("nav") / "short-goal.toml"
    path.write_text(SCENARIO)
    return path


@pytest.fixture(scope="module")
def planned_run(short_goal: Path, tmp_path_factory) -> tuple[navigator.Navigator, Path]:
    """The tactile-only arm (stop after the planned steps), recorded."""
    sc = scenario_mod.load_scenario(str(short_goal))
    trace = tmp_path_factory.mktemp("nav-trace") / "planned.mcap"
    navs: list[navigator.Navigator] = []

    def navigate(run) -> None:
        args = ("tripod", PERIOD_S, 0.05, 0.3)
        est = navigator.make_estimator("planned", None, *args)
        navs.append(navigator.attach(run, run.world, est, *args, 3))
    th.simulate(sc, 4, 6 * PERIOD_S, str(trace), navigate)
    return navs[0], trace


@pytest.fixture(scope="module")
def tiny_model(tmp_path_factory) -> Path:
    """A GRNN trained for one epoch on synthetic walks: enough to drive the node."""
    tmp = tmp_path_factory.mktemp("nav-model")
    runs, rows = data.synthetic(6, 0, 1)
    ds = data.write(tmp / "train", runs, rows, data.feature_meta())
    train.main(str(ds), str(tmp / "model.pt"), epochs=1)
    return tmp / "model.pt"


def test_the_navigator_sees_the_steps_the_dataset_reads_from_the_trace(planned_run):
    nav, trace = planned_run
    rows, _ = rows_from_trace(trace)
    assert len(nav.rows) == len(rows) == 3
    for live, logged in zip(nav.rows, rows):
        assert live.step == logged.step and live.t_us == logged.t_us
        assert live.sensing == pytest.approx(logged.sensing, abs=1e-9)
        assert live.error_m == pytest.approx(logged.error_m, abs=1e-9)


def test_planned_steps_stop_the_walk_and_the_body_stays(planned_run):
    nav, trace = planned_run
    assert nav.summary()["stop_step"] == 3 and nav.known_steps == 2
    assert nav.heading_rad is None        # tactile only: no correction either
    with Trace(trace) as tr:
        body = [(m.log_time_ns / 1e9, v["translation"]["x"]) for m, v in tr.decoded([T_BODY])]
    t_stop = nav.rows[-1].t_us * 1e-6
    after = [x for t, x in body if t > t_stop + 1.0]   # legs back to neutral by then
    before = [x for t, x in body if t <= t_stop]
    assert before[-1] - before[0] > 0.1, "the robot walked before the stop"
    assert after and max(after) - min(after) < 0.005, "the robot stands still after the stop"


def _hexhil_json(*args: str) -> tuple[int, dict, str]:
    """``hexhil`` in a child process; also reports whether torch got imported."""
    code = ("import sys, json; from hexhil.cli import main; rc = main(sys.argv[1:]); "
            "print(json.dumps({'torch': 'torch' in sys.modules})); sys.exit(rc)")
    p = subprocess.run([sys.executable, "-c", code, *args], cwd=ROOT, capture_output=True,
                       text=True, timeout=300)
    lines = p.stdout.strip().splitlines()
    summary = json.loads(lines[-2]) if len(lines) > 1 and lines[-2].startswith("{") else {}
    summary["_torch"] = json.loads(lines[-1])["torch"] if lines else None
    return p.returncode, summary, p.stderr


def test_run_with_the_eq_8_14_navigator_stops_after_the_known_path(short_goal):
    rc, s, err = _hexhil_json("run", str(short_goal), "--navigator", "model", "--json")
    assert rc == 0, err
    n = s["navigator"]
    assert n["kind"] == "model" and n["planned_steps"] == 3 and n["known_steps"] == 2
    assert n["stop_step"] is not None and n["stop_step"] > 2
    assert s["state"] == "stopped"
    # it stopped where it predicted less than half a step to go (or past the goal)
    assert n["predicted_to_go_m"] < 0.5 * 0.036 * PERIOD_S
    # at the last fix it turned toward the goal: the heading that cancels the fix's
    # lateral offset and yaw, within the navigator's bound
    assert n["heading_deg"] is not None and 0 < abs(n["heading_deg"]) <= 20.06
    assert s["_torch"] is False


def test_run_with_the_grnn_navigator_feeds_it_every_step(short_goal, tiny_model):
    rc, s, err = _hexhil_json("run", str(short_goal), "--navigator", "grnn", "--model",
                              str(tiny_model), "--duration", str(4 * PERIOD_S), "--json")
    assert rc == 0, err
    n = s["navigator"]
    assert n["kind"] == "grnn" and n["known_steps"] == 2
    assert isinstance(n["predicted_to_go_m"], float)
    assert s["_torch"] is True


@pytest.mark.parametrize("args,needle", [
    (["--navigator", "grnn"], "needs --model"),
    (["--navigator", "grnn", "--model", "/nonexistent.pt"], "no such model file"),
])
def test_bad_navigator_options_are_one_line(short_goal, capsys, tmp_path, args, needle):
    out = tmp_path / "run.mcap"
    assert cli(["run", str(short_goal), *args, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and "\n" not in err
    assert not out.exists(), "refused before anything was opened"


@pytest.mark.parametrize("scenario,needle", [
    ("scenarios/flat-tripod.toml", "no gait.distance_m"),
    ("scenarios/beams-flimsy.toml", "walks the hexapod"),
])
def test_a_scenario_without_a_goal_is_refused(capsys, scenario, needle):
    assert cli(["run", str(ROOT / scenario), "--navigator", "model"]) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and "\n" not in err


def test_closed_loop_refuses_training_terrains_and_traces_without_speeds(tiny_model, tmp_path,
                                                                         capsys):
    runs, rows = data.synthetic(2, 3, 1)     # terrain seeds 1-2: in the model's training set
    seen = data.write(tmp_path / "seen", runs, rows, data.feature_meta())
    assert cli(["grnn", "closed-loop", str(tiny_model), str(seen)]) == 2
    assert "were in the model's training set" in capsys.readouterr().err
    runs, rows = data.synthetic(2, 3, 101)
    unseen = data.write(tmp_path / "unseen", runs, rows, data.feature_meta())
    assert cli(["grnn", "closed-loop", str(tiny_model), str(unseen)]) == 2
    assert "no calibrated speeds" in capsys.readouterr().err
