"""Seed 003's analytic positional-error model (Sections 2.5 and 2.7, Eq. 8-14), evaluated
from one run's logged per-leg events.

The paper's inputs and how a run supplies them:

- the obstacle interactions (the double sum over N obstacles and n/2 legs, Eq. 8 and 11):
  every closing of a tibia switch is one leg meeting one obstacle;
- the single-leg lost distance ``dL`` ("how much the robot is pushing leg backward",
  Sec. 2.5): while a switch is closed, the body falls behind the nominal walking speed; the
  shortfall of each 10 Hz ground-truth interval is shared among the legs closed in it, so two
  legs caught at once do not count the same lost distance twice;
- the side of each leg: a leg held back on the left turns the robot left (+alpha), on the
  right, right (-alpha) (Fig. 9);
- ``a``, the robot's width at its configuration (Eq. 12), from the geometry;
- ``S * l_i`` (Eq. 10), the nominal distance walked when the last interaction ended.

Nothing here reads the measured end pose: the prediction uses the events and the body's
progress while legs were caught, and is printed beside the measured errors.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable, Sequence

LEFT_LEGS = (0, 1, 2)  # LF, LM, LH; 3-5 are RF, RM, RH


@dataclass
class Prediction:
    """Eq. 8-14 for one run: errors in metres and radians, plus the per-hit inputs."""

    dx_m: float            # Eq. 8
    dy_m: float            # Eq. 9
    dalpha_rad: float      # Eq. 11
    remaining_m: float     # R, Eq. 10
    hits: int
    lost_m: list[float] = field(default_factory=list)       # dL per hit
    alpha_rad: list[float] = field(default_factory=list)    # signed alpha_k per hit, Eq. 14


def alpha_k(lost_m: float, width_m: float) -> float:
    """Eq. 12-14: the turn caused by one leg losing ``lost_m`` on a robot ``width_m`` wide."""
    beta = math.acos(min(1.0, lost_m / (2.0 * width_m)))   # Eq. 12
    return math.pi - 2.0 * beta                             # Eq. 13-14 (alpha1 + alpha2)


def lateral_error(remaining_m: float, dx_m: float, dalpha_rad: float) -> float:
    """Eq. 9: dy = (R - dx) sin(dalpha) / sin(90 deg - dalpha)."""
    return (remaining_m - dx_m) * math.sin(dalpha_rad) / math.sin(math.pi / 2 - dalpha_rad)


def predict(events: Iterable[tuple[int, int, bool]], trajectory: Sequence[tuple[int, float, float, float]],
            speed_m_s: float, distance_m: float, width_m: float) -> Prediction:
    """Evaluate Eq. 8-14.

    ``events``: (t_us, leg, closed) switch edges in time order; ``trajectory``: (t_us, x_m,
    y_m, yaw_rad) ground-truth samples; ``speed_m_s``: the gait's nominal body speed (from
    flat-ground calibration); ``distance_m``: d; ``width_m``: a.
    """
    edges = sorted(events)
    closed_since: dict[int, int] = {}
    windows: list[tuple[int, int, int]] = []   # (leg, t_close_us, t_open_us)
    for t_us, leg, closed in edges:
        if closed and leg not in closed_since:
            closed_since[leg] = t_us
        elif not closed and leg in closed_since:
            windows.append((leg, closed_since.pop(leg), t_us))
    t_end = trajectory[-1][0] if trajectory else 0
    windows += [(leg, t0, t_end) for leg, t0 in closed_since.items()]
    windows.sort(key=lambda w: w[1])
    lost = [0.0] * len(windows)
    for (t0, x0, _, _), (t1, x1, _, _) in zip(trajectory, trajectory[1:]):
        shortfall = speed_m_s * (t1 - t0) * 1e-6 - (x1 - x0)
        caught = [i for i, (_, a, b) in enumerate(windows) if a < t1 and b > t0]
        if shortfall > 0 and caught:
            for i in caught:
                lost[i] += shortfall / len(caught)
    alphas = [alpha_k(dl, width_m) * (1 if leg in LEFT_LEGS else -1)
              for dl, (leg, _, _) in zip(lost, windows)]
    dx = sum(lost)                                           # Eq. 8
    dalpha = sum(alphas)                                     # Eq. 11
    t_last = max((b for _, _, b in windows), default=0)
    remaining = distance_m - speed_m_s * t_last * 1e-6       # Eq. 10, S * l_i walked nominally
    dy = lateral_error(remaining, dx, dalpha) if abs(dalpha) < math.pi / 2 else math.copysign(
        math.inf, dalpha)
    return Prediction(dx_m=dx, dy_m=dy, dalpha_rad=dalpha, remaining_m=remaining,
                      hits=len(windows), lost_m=lost, alpha_rad=alphas)
