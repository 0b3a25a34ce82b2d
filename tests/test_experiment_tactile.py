"""The tactile-hexapod experiment: scenarios, plan, executor, and (with the Simulator) runs."""
import pytest

from host_tools.experiments import tactile_hexapod as th
from host_tools.experiments.executor import Executor
from host_tools.errors import UserError
from hil.world.hexapod import HexapodWorld


def _square(x):
    return x * x


def test_executor_keeps_spec_order_in_process_and_in_a_pool():
    assert Executor(1, progress=False).map(_square, [3, 1, 2], "t") == [9, 1, 4]
    assert Executor(2, progress=False).map(_square, list(range(7)), "t") == [i * i for i in range(7)]
    with pytest.raises(UserError):
        Executor(0)


def test_executor_on_a_dask_cluster():
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        ex = Executor(scheduler=cluster.scheduler_address, progress=False)
        assert ex.map(_square, [5, 6, 7], "t") == [25, 36, 49]


def test_unreachable_scheduler_is_a_user_error():
    with pytest.raises(UserError, match="Dask scheduler"):
        Executor(scheduler="tcp://127.0.0.1:9", progress=False).map(_square, [1], "t")


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
    assert a["firmware"]["tactile"] is False and b["firmware"]["tactile"] is True
    assert a["gait"]["max_obstacle_height_m"] == 0.08
    assert HexapodWorld(a, 2).obstacles == HexapodWorld(b, 2).obstacles
    flat = th.scenario_for(th.RunSpec("calibration", "tripod", 2.0, True, 0, periods=3))
    assert HexapodWorld(flat, 0).obstacles == []
