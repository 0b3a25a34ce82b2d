"""Closing the loop (beyond the paper): a host node on the run's CAN bus that walks
the robot to its goal by predicting how far short it will end.

Seed 003 walks a fixed number of steps (Sec. 3.3) and measures the shortfall afterwards;
Sec. 2.6 predicts it. Here the prediction decides when to stop. Every gait period the
navigator closes one step (``features.StepSampler``, fed from the ``tactile`` frames on
CAN and the 10 Hz ground-truth samples) and asks its estimator for the body's longitudinal
error after it. The robot's position is known only on the known path (the first
``features.KNOWN_FRACTION`` of the planned steps, as a localisation fix would give it); after that
the estimator works from what the robot senses onboard. At the first step boundary after
the known path where the predicted distance still to go is under half a step's advance,
it sends ``gait_command`` stop. At the last fix it also turns the walking direction toward
the goal (``heading_command``, each leg taking it at its next lift-off): the lateral error
and the heading the fix shows are corrected, later turns are not (nothing measures them).

Estimators (``step(row, known) -> error_m``, the body's error = planned x - actual x):

* ``GrnnEstimator``: the trained GRNN (Fig. 8), its own predictions fed back;
* ``ModelEstimator``: Eq. 8 on the unobserved part: each switch press loses the mean
  dL per hit that Eq. 8-14 (``hexhil.papers.tactile_hexapod.error_model``) measured on the known path, and
  every step loses the flat-ground shortfall of the nominal speed against the calibrated
  one;
* ``PlannedSteps``: no prediction: stop after the planned steps (tactile only).
"""
from __future__ import annotations

import math
from typing import Any

from hexhil.hil.canbus.bus import Endpoint, message, t_us_of
from hexhil.hil.run.lockstep import BODY_SAMPLE_US
from hexhil.hil.seams import FirmwareWorld
from hexhil.plugins import RunWithNodes
from hexhil.papers.tactile_hexapod import error_model
from hexhil.papers.tactile_hexapod.grnn.features import LEGS, StepRow, StepSampler, known_steps
from hexhil.protocol import can_frames as cf
from hexhil.protocol import hexapod

MAX_HEADING_RAD = 0.35   # a correction beyond 20 deg means the fix is not to be trusted

KINDS = ("planned", "model", "grnn")


class Estimator:
    """What every estimator is told; only Eq. 8-14 needs the switch edges and the path."""

    predicts = True

    def switches(self, t_us: int, bits: int) -> None:
        """The switch levels of a ``tactile`` frame."""

    def pose(self, t_us: int, x_m: float, y_m: float, yaw_rad: float) -> None:
        """A ground-truth sample on the known path (from the start)."""

    def step(self, row: StepRow, known: bool) -> float:
        raise NotImplementedError


class PlannedSteps(Estimator):
    """Tactile only: the error is not predicted, the walk ends after the planned steps."""

    predicts = False

    def step(self, row: StepRow, known: bool) -> float:
        return 0.0


class GrnnEstimator(Estimator):
    """The GRNN of Sec. 2.6: known errors observed, then its own predictions fed back."""

    def __init__(self, predictor: Any) -> None:
        self.predictor = predictor
        predictor.reset()

    def step(self, row: StepRow, known: bool) -> float:
        out = self.predictor.step(row.sensing, row.error_m if known else None)
        errors = row.error_m if known else out
        return sum(errors) / len(errors)


class ModelEstimator(Estimator):
    """Eq. 8 after the known path, with dL per hit measured on it (Eq. 8-14's inputs)."""

    def __init__(self, speed_m_s: float, nominal_m_s: float, period_s: float,
                 distance_m: float, step_length_m: float) -> None:
        self.speed_m_s, self.period_s, self.distance_m = speed_m_s, period_s, distance_m
        self.drift_m = (nominal_m_s - speed_m_s) * period_s   # flat-ground loss per step
        # no hit on the known path: Sec. 2.5's "the robot can hit the obstacle at any time
        # during the leg transfer phase", so half a step is lost on average
        self.fallback_lost_m = step_length_m / 2
        self.events: list[tuple[int, int, bool]] = []
        self.trajectory: list[tuple[int, float, float, float]] = []
        self.lost_per_hit_m: float | None = None
        self.error_m = 0.0
        self._levels = 0
        self._presses = 0     # switch closings since the last step closed

    def switches(self, t_us: int, bits: int) -> None:
        """Switch edges, as Eq. 8-14 takes them."""
        for leg in range(LEGS):
            b = 1 << leg
            if (bits ^ self._levels) & b:
                self.events.append((t_us, leg, bool(bits & b)))
                self._presses += 1 if bits & b else 0
        self._levels = bits

    def pose(self, t_us: int, x_m: float, y_m: float, yaw_rad: float) -> None:
        self.trajectory.append((t_us, x_m, y_m, yaw_rad))

    def step(self, row: StepRow, known: bool) -> float:
        presses, self._presses = self._presses, 0
        if known:
            self.error_m = sum(row.error_m) / len(row.error_m)
            return self.error_m
        if self.lost_per_hit_m is None:
            p = error_model.predict(self.events, self.trajectory, self.speed_m_s,
                                    self.distance_m, 2 * hexapod.neutral_foot(1)[1])
            self.lost_per_hit_m = p.dx_m / p.hits if p.hits else self.fallback_lost_m
        self.error_m += self.drift_m + presses * self.lost_per_hit_m   # Eq. 8
        return self.error_m


class Navigator:
    """The host node (``period_us``, ``tick``) that stops the walk at the predicted goal."""

    period_us = BODY_SAMPLE_US    # at the trace's ground-truth instants, as the dataset reads
    first_tick_us = 0

    def __init__(self, port: Endpoint, world: FirmwareWorld, estimator: Estimator, gait: str,
                 period_s: float, step_length_m: float, distance_m: float, planned_steps: int,
                 speed_m_s: float | None = None) -> None:
        self.port, self.world, self.estimator = port, world, estimator
        self.distance_m = distance_m
        self.planned_steps = planned_steps
        self.known_steps = known_steps(planned_steps)
        nominal = hexapod.speed_m_s(gait, step_length_m, period_s)
        self.advance_m = (speed_m_s or nominal) * period_s   # what one more step gains
        self.sampler = StepSampler(gait, period_s, step_length_m)
        self.x0_m: float | None = None
        self.stop_step: int | None = None
        self.heading_rad: float | None = None
        self.predicted: list[tuple[int, float]] = []   # (step, predicted distance to go, m)
        self.rows: list[StepRow] = []                  # the steps as the navigator saw them

    def tick(self, t_us: int) -> None:
        for msg in self.port.frames():
            try:
                name, sig = cf.decode(msg.arbitration_id, bytes(msg.data))
            except ValueError:
                continue
            if name == "tactile":
                self.sampler.tactile(t_us_of(msg), sig["switches"], sig["overcoming"],
                                     sig["step_counter"])
                self.estimator.switches(t_us_of(msg), sig["switches"])
        pose = self.world.body_pose()
        if self.x0_m is None:
            self.x0_m = pose.x_m
        row = self.sampler.truth(t_us, pose.x_m, pose.y_m, pose.yaw_rad,
                                 self.world.joint_positions())
        if row is None or row.step <= self.known_steps:
            self.estimator.pose(t_us, pose.x_m - self.x0_m, pose.y_m, pose.yaw_rad)
        if row is not None:
            self.rows.append(row)
            if self.stop_step is None:
                self._closed(row)

    def _closed(self, row: StepRow) -> None:
        known = row.step <= self.known_steps
        error_m = self.estimator.step(row, known)
        if row.step == self.known_steps and self.estimator.predicts:
            self._head_for_goal(row)
        if self.estimator.predicts:
            to_go_m = self.distance_m - (row.planned_x_m - error_m)
            self.predicted.append((row.step, to_go_m))
            done = not known and to_go_m < self.advance_m / 2
        else:
            done = row.step >= self.planned_steps
        if done:
            self.stop_step = row.step
            self.port.send(message("gait_command", command=cf.COMMAND_STOP, gait=0,
                                   step_length_m=0, step_height_m=0, period_s=0))

    def _head_for_goal(self, row: StepRow) -> None:
        """Walk from the fix's pose straight at the goal (d, 0) of the start frame."""
        bearing = math.atan2(-row.body_y_m, self.distance_m - row.body_x_m)
        eps = max(-MAX_HEADING_RAD, min(MAX_HEADING_RAD, bearing - row.yaw_rad))
        self.heading_rad = eps
        self.port.send(message("heading_command", direction_rad=eps))

    def summary(self) -> dict[str, Any]:
        last = self.predicted[-1][1] if self.predicted else None
        return {"planned_steps": self.planned_steps, "known_steps": self.known_steps,
                "stop_step": self.stop_step,
                "heading_deg": None if self.heading_rad is None
                else round(math.degrees(self.heading_rad), 2),
                "predicted_to_go_m": None if last is None else round(last, 4)}


def make_estimator(kind: str, model_path: str | None, gait: str, period_s: float,
                   step_length_m: float, distance_m: float,
                   speed_m_s: float | None = None) -> Estimator:
    """The estimator of one of ``KINDS`` (torch is imported only for grnn); a model file
    that will not load is refused here, before a run starts."""
    if kind == "grnn":
        from hexhil.papers.tactile_hexapod.grnn.model import load
        return GrnnEstimator(load(model_path))
    if kind == "model":
        nominal = hexapod.speed_m_s(gait, step_length_m, period_s)
        return ModelEstimator(speed_m_s or nominal, nominal, period_s, distance_m,
                              step_length_m)
    if kind == "planned":
        return PlannedSteps()
    raise ValueError(f"unknown navigator {kind!r}")


def attach(sim: RunWithNodes, world: FirmwareWorld, estimator: Estimator, gait: str, period_s: float,
           step_length_m: float, distance_m: float, planned_steps: int,
           speed_m_s: float | None = None) -> Navigator:
    """A navigator on ``sim``'s CAN bus, ticked with its ground truth."""
    nav = Navigator(sim.can.endpoint("rx"), world, estimator, gait, period_s, step_length_m,
                    distance_m, planned_steps, speed_m_s)
    sim.add_node(nav)
    return nav
