"""The GRNN's per-step features (seed 003 Sec. 2.6, Fig. 8), sampled once per gait period.

One ``StepRow`` per completed step k (k = 1..N gait periods): the planned position (the
firmware's dead reckoning), the ground-truth body pose, what the robot senses onboard, and
the target, the longitudinal error of each leg's hip. ``StepSampler`` is fed a run's events
in time order, from a trace (``hexhil.papers.tactile_hexapod.grnn.dataset``) or live from the CAN bus and the
world (the navigator), so it knows neither.

Pure Python and ``protocol.hexapod``: no torch, no numpy.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

from hexhil.protocol import hexapod

FEATURE_VERSION = "grnn-features-1"   # bump when a definition below changes
LEGS = 6                               # LF, LM, LH, RF, RM, RH (protocol/hexapod.py order)
# The known path X (Sec. 2.6): the first half of the planned steps, with ground-truth fixes;
# the future path P: the rest. The paper does not say where X ends; half is our choice.
KNOWN_FRACTION = 0.5
M_MAX = 64                             # cap on the future steps m rolled out

SENSING: tuple[str, ...] = (
    tuple(f"switch_{n}" for n in hexapod.LEGS)
    + tuple(f"overcoming_{n}" for n in hexapod.LEGS)
    + tuple(f"foot_x_{n}_m" for n in hexapod.LEGS)
    + tuple(f"foot_z_{n}_m" for n in hexapod.LEGS)
    + ("planned_step_m",)
)

# What each feature means, written into the dataset's sidecar.
DEFINITIONS: dict[str, str] = {
    "step": "k = 1..N: the step closes when the tactile frame's step_counter (lift-offs "
            "over all legs, firmware/tactile.py ObstacleRule.steps) reaches 6k; the row is "
            "taken at the first 10 Hz ground-truth sample at or after that frame",
    "planned_x_m": "k * v * T: the firmware's dead reckoning at the end of period k, v = "
                   "protocol.hexapod.speed_m_s(gait, l_i, T)",
    "body_x_m, body_y_m, yaw_rad": "ground truth, displacement from the run's first sample",
    "switch_<leg>": "1 if the leg's tibia switch was pressed in any tactile frame of step k",
    "overcoming_<leg>": "1 if the leg was on the obstacle trajectory (Eq. 5-7) in any "
                        "tactile frame of step k",
    "foot_x_<leg>_m, foot_z_<leg>_m": "foot position in the body frame at the row's sample, "
                                      "forward kinematics (protocol.hexapod.Leg.fk) of the "
                                      "joint angles",
    "planned_step_m": "v * T: the planned advance per step (tells the gaits apart)",
    "error_m": "per leg: planned hip x - actual hip x (m); planned hip = planned_x + mount "
               "on a straight path, actual hip = body pose and yaw applied to the mount "
               "(protocol.hexapod.MOUNTS); the mean over the legs is planned_x - body_x",
}

_STEP_LIFT_OFFS = LEGS   # one gait period lifts every leg once (Fig. 13)
_LEG_MODELS = [hexapod.Leg(i) for i in range(LEGS)]   # nominal calibration: offsets 0


@dataclass
class StepRow:
    """One completed step: times in us, lengths in m, angles in rad."""

    step: int
    t_us: int
    planned_x_m: float
    body_x_m: float
    body_y_m: float
    yaw_rad: float
    sensing: list[float]
    error_m: list[float]


def hip_errors_m(planned_x_m: float, x_m: float, y_m: float, yaw_rad: float) -> list[float]:
    """Longitudinal error of each hip: where the plan puts it minus where it is."""
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    return [(planned_x_m + mx) - (x_m + c * mx - s * my) for mx, my, _ in hexapod.MOUNTS]


def feet_in_body_m(joints_rad: Sequence[float]) -> list[tuple[float, float, float]]:
    """Each foot in the body frame from the 18 servo angles (servo-ID order, as the world's
    ``joint_positions()`` and the /joints topic give them)."""
    out = []
    for i, leg in enumerate(_LEG_MODELS):
        q = [leg.joint_rad(j, joints_rad[3 * i + j]) for j in range(3)]
        out.append(leg.fk(*q))
    return out


def known_steps(periods: int) -> int:
    """n, the steps of the known path X, for a walk of ``periods`` planned steps."""
    return math.ceil(KNOWN_FRACTION * periods)


class StepSampler:
    """Feeds on the run's events in time order; emits one StepRow per gait period."""

    def __init__(self, gait: str, period_s: float, step_length_m: float) -> None:
        if gait not in hexapod.GAITS:
            raise ValueError(f"unknown gait {gait!r}")
        self.planned_step_m = hexapod.speed_m_s(gait, step_length_m, period_s) * period_s
        self._closed = 0          # steps closed by the step counter
        self._emitted = 0         # rows emitted
        self._switches = 0        # OR of the bits seen in the step under way
        self._overcoming = 0
        self._closing = (0, 0)    # those of the step closed last, for its row
        self._origin: tuple[float, float, float] | None = None

    def tactile(self, t_us: int, switches: int, overcoming: int, step_counter: int) -> None:
        """A decoded ``tactile`` CAN frame (protocol/can_frames.py)."""
        self._switches |= switches
        self._overcoming |= overcoming
        if step_counter // _STEP_LIFT_OFFS > self._closed:
            self._closed = step_counter // _STEP_LIFT_OFFS
            self._closing = (self._switches, self._overcoming)
            self._switches = self._overcoming = 0

    def truth(self, t_us: int, x_m: float, y_m: float, yaw_rad: float,
              joints_rad: Sequence[float]) -> StepRow | None:
        """A 10 Hz ground-truth sample (world pose, 18 servo angles). Returns the row of a
        step that has just completed, else None."""
        if self._origin is None:
            self._origin = (x_m, y_m, yaw_rad)
        if self._closed <= self._emitted:
            return None
        self._emitted += 1
        x0, y0, yaw0 = self._origin
        x, y, yaw = x_m - x0, y_m - y0, _wrap(yaw_rad - yaw0)
        planned = self._emitted * self.planned_step_m
        feet = feet_in_body_m(joints_rad)
        switches, overcoming = self._closing
        sensing = ([float(switches >> i & 1) for i in range(LEGS)]
                   + [float(overcoming >> i & 1) for i in range(LEGS)]
                   + [f[0] for f in feet] + [f[2] for f in feet] + [self.planned_step_m])
        return StepRow(self._emitted, t_us, planned, x, y, yaw, sensing,
                       hip_errors_m(planned, x, y, yaw))


def _wrap(a_rad: float) -> float:
    return math.atan2(math.sin(a_rad), math.cos(a_rad))
