"""Seed 003 (an 18-DOF hexapod with a limit switch on each leg): the tactile experiment
(``experiment``, ``report``), the analytic error model of Eq. 8-14 (``error_model``) and the
GRNN positional-error predictor (``grnn``). Importing it registers the navigators ``model``
and ``grnn`` of ``hexhil run --navigator`` (host_tools/plugins.py); nothing heavy loads
until one is used."""
from __future__ import annotations

from typing import Callable

from hexhil.hil.scenario import Scenario, WorldKind
from hexhil import plugins
from hexhil.protocol import hexapod
from hexhil.protocol.errors import UserError


def _plan(kind: str) -> plugins.NavigatorPlan:
    def plan(sc: Scenario, model_path: str | None) -> Callable:
        """Checks the scenario and makes the estimator (a GRNN file loaded) now; the goal
        ``gait.distance_m``, planned at the gait's nominal speed."""
        if sc.world.kind is not WorldKind.HEXAPOD:
            raise UserError(f"the {kind} navigator walks the hexapod: this scenario's world "
                            f"is {sc.world.kind.value if sc.world.kind else 'none'}")
        if sc.gait.distance_m is None:
            raise UserError(f"the {kind} navigator needs the goal: the scenario has no "
                            "gait.distance_m")
        if kind == "grnn" and not model_path:
            raise UserError("the grnn navigator needs model_path, a model file (hexhil grnn "
                            "train)", params=("model_path",))
        from hexhil.papers.tactile_hexapod.grnn import navigator

        gait, period_s = sc.gait.name, sc.gait.period_s
        step_m = sc.gait.step_length_m or hexapod.STEP_LENGTH_M
        d = sc.gait.distance_m
        steps = hexapod.periods_for_distance(d, hexapod.speed_m_s(gait, step_m, period_s),
                                             period_s)
        estimator = navigator.make_estimator(kind, model_path, gait, period_s, step_m, d)
        return lambda run: navigator.attach(run, run.world, estimator, gait, period_s, step_m,
                                            d, steps)
    return plan


for _kind in ("model", "grnn"):
    plugins.register_navigator(_kind, _plan(_kind))
