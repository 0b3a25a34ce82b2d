"""The tactile-hexapod experiment: scenarios, plan, executor, and (with the Simulator) runs."""
import pytest

from hexhil.papers.tactile_hexapod import experiment as th
from hexhil.executor import Executor
from hexhil.protocol.errors import UserError
from hexhil.hil.world.hexapod_world import HexapodWorld


def _square(x):
    return x * x


def test_executor_keeps_spec_order_in_process_and_in_a_pool():
    assert Executor(1).map(_square, [3, 1, 2], "t") == [9, 1, 4]
    assert Executor(2).map(_square, list(range(7)), "t") == [i * i for i in range(7)]
    with pytest.raises(UserError):
        Executor(0)


def test_executor_reports_each_run_done_to_its_progress_callback():
    for workers in (1, 2):
        seen = []
        Executor(workers, progress=lambda *a: seen.append(a)).map(_square, [3, 1, 2], "t")
        assert seen == [("t", n, 3, "") for n in range(4)]


def test_executor_on_a_dask_cluster():
    import distributed
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        ex = Executor(scheduler=cluster.scheduler_address)
        assert ex.map(_square, [5, 6, 7], "t") == [25, 36, 49]


def test_unreachable_scheduler_is_a_user_error():
    with pytest.raises(UserError, match="Dask scheduler"):
        Executor(scheduler="tcp://127.0.0.1:9").map(_square, [1], "t")


def test_plan_covers_the_papers_protocol():
    periods = {(g, d): 10 for g in th.GAITS for d in (1.0, 2.0)}
    full = th.plan(False, 3, periods)
    stages = [s.stage for s in full]
    assert stages.count("calibration") == 4                   # Table 1: 2 gaits x 2 distances
    assert stages.count("without") == 2 * 2 * 3              # Fig. 16: low density, 1 m
    assert stages.count("with") == 2 * 2 * 2 * 2 * 3         # Fig. 17-20: 16 cases
    assert all(s.density == "low" and s.distance_m == 1.0 and not s.tactile
               for s in full if s.stage == "without")
    quick = th.plan(True, 1, periods)
    assert {s.distance_m for s in quick} == {1.0} and len(quick) == 2 + 4 + 8


def test_run_scenarios_are_valid_and_pair_terrain_across_the_method():
    base = th.RunSpec("without", "wave", 1.0, False, 2, "low", "large", periods=3)
    paired = th.RunSpec("with", "wave", 1.0, True, 2, "low", "large", periods=3)
    a, b = th.scenario_for(base), th.scenario_for(paired)
    assert a.firmware.tactile is False and b.firmware.tactile is True
    assert a.gait.max_obstacle_height_m == 0.08
    assert HexapodWorld(a, 2).obstacles == HexapodWorld(b, 2).obstacles
    flat = th.scenario_for(th.RunSpec("calibration", "tripod", 2.0, True, 0, periods=3))
    assert HexapodWorld(flat, 0).obstacles == []


def _one_obstacle(tactile: bool):
    """Tripod, firmware under micropython, one 4.5 cm obstacle in the left-front leg's path."""
    from hexhil.hil.run.lockstep import Simulator

    spec = th.RunSpec("with" if tactile else "without", "tripod", 1.0, tactile, 0, periods=4,
                      model="ideal")   # the firmware pipeline on the regression world
    sc = th.scenario_for(spec).overlay({
        "world": {"terrain": "obstacles", "obstacles": [
            {"x_m": 0.36, "y_m": 0.19, "length_m": 0.03, "width_m": 0.08, "height_m": 0.045}]},
        "gait": {"max_obstacle_height_m": 0.05}})
    world = HexapodWorld(sc, 0)
    result = Simulator(sc, 0, world=world).run(spec.duration_s)
    return world, result


def test_switch_fires_firmware_switches_trajectory_and_the_method_gets_nearer():
    with_w, with_r = _one_obstacle(True)
    without_w, without_r = _one_obstacle(False)
    for w in (with_w, without_w):
        assert w.switches.presses[0] > 0 and sum(w.switches.presses[1:]) == 0   # only LF hit it
    over = [e for e in with_r.tactile_events if e.get("overcoming")]
    assert over and over[0]["leg"] == "LF"
    assert over[0]["step_length_m"] == pytest.approx(0.1)     # Eq. 6: l_k = 2 l_i
    assert over[0]["step_height_m"] == pytest.approx(0.07)    # Eq. 7: h_k = H + 2 cm
    assert not [e for e in without_r.tactile_events if e.get("overcoming")]
    a, b = with_w.body_pose(), without_w.body_pose()
    assert a.x_m > b.x_m + 0.01                 # nearer the goal with the method
    assert abs(a.yaw_rad) < abs(b.yaw_rad)      # and turned less by the caught leg


def test_runs_report_errors_model_table_and_plots(tmp_path):
    speed = 0.0326
    runs = [th.run_one(th.RunSpec(stage, "tripod", 1.0, stage == "with", 1, "low", "small", periods=2), speed)
            for stage in ("without", "with")]
    runs.append(th.run_one(th.RunSpec("calibration", "tripod", 1.0, True, 0, periods=2), speed))
    for r in runs:
        assert r["dx_m"] == pytest.approx(1.0 - r["x_m"])
        assert r["rel_error"] == pytest.approx(r["error_m"])
        assert "model_dx_m" in r and r["model_hits"] >= 0
    assert runs[2]["presses"] == [0] * 6 and runs[2]["model_dx_m"] == 0.0
    result = {"model": "real", "obstacle_body": th.OBSTACLE_BODY, "speed_m_s": {"tripod": speed},
              "periods": {"tripod 1 m": 2}, "runs": runs}
    md = th.markdown(result, quick=True)
    assert "| tripod | low | 1 | small | 1 |" in md and "~24 %" in md
    assert "world model 'real', fixed obstacles" in md
    paths = th.plots(result, tmp_path)
    assert all(p.stat().st_size > 5000 for p in paths)


@pytest.mark.slow
def test_quick_sweep_from_the_command_line(tmp_path):
    """The paper's headline, the method beats no method, on the default world: the real model
    with obstacles the legs get stuck behind, as the paper's were. Its loose wooden obstacles
    (``--obstacles free``) are shoved aside, and there the method's longer steps cost more
    than they save (docs/hexapod-world.md)."""
    import json
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-m", "hexhil.cli", "experiment", "tactile-hexapod", "--quick",
                           "--out", str(tmp_path), "--workers", "2", "--json"],
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-2000:]
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    assert summary["runs"] == 14
    assert summary["rel_error_with"] < summary["rel_error_without"]
    assert (tmp_path / "results.md").exists() and len(summary["plots"]) == 4


def test_an_experiment_run_records_its_trace(tmp_path):
    from hexhil.trace.reader import info

    spec = th.RunSpec("with", "tripod", 1.0, True, 1, "low", "small", periods=1)
    r = th.run_one(spec, 0.0326, str(tmp_path))
    assert r["trace"] == str(tmp_path / "with-tripod-low-small-1m-seed1-tactile.mcap")
    summary = info(r["trace"])
    topics = {t["topic"]: t["messages"] for t in summary["topics"]}
    assert topics["/body"] > 0 and topics["/serial"] > 0 and topics["/joints"] > 0
    assert summary["metadata"]  # scenario, seed, runtime
    assert summary["end_s"] == pytest.approx(r["sim_s"], abs=0.1)


def test_cli_prints_the_experiment_style_not_the_report(tmp_path, monkeypatch, capsys):
    """The whole CLI path on three real short runs (the sweep itself is the slow test)."""
    from experiment_output import check_output
    from hexhil.cli import main as cli

    speed = 0.0326
    runs = [th.run_one(th.RunSpec(stage, "tripod", 1.0, stage == "with", 1, "low", "small",
                                  periods=2), speed) for stage in ("without", "with")]
    sweep = {"model": "real", "obstacle_body": th.OBSTACLE_BODY, "speed_m_s": {"tripod": speed},
             "periods": {"tripod 1 m": 2}, "runs": runs}
    monkeypatch.setattr(th, "run_sweep", lambda *a: dict(sweep))
    assert cli(["experiment", "tactile-hexapod", "--quick", "--out", str(tmp_path), "--json"]) == 0
    printed = capsys.readouterr().out
    summary = check_output(printed, "tactile-hexapod", tmp_path)
    assert summary["runs"] == 2 and "mean relative goal error" in printed
    assert "# Seed 003" not in printed and (tmp_path / "results.md").read_text().startswith("# Seed 003")
