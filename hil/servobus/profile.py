"""The X series' trapezoid velocity profile (e-manual XL430-W250-T, "Profile Velocity"
and "Profile Acceleration"): the Position Trajectory that the servo's position loop
follows after a new Goal Position.

Velocity-based profile (Drive Mode bit 2 clear, the default): accelerate at the profile
acceleration, cruise at the profile velocity, decelerate to stop at the goal; a short
move never reaches the cruise speed (a triangle). Either value 0 means infinite.
Our choices where the manual is silent: a new goal starts its profile from the present
trajectory speed when that points towards the new goal, else from rest; a start too fast
to stop in time is slowed to what can.
"""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass
class Trapezoid:
    """One profiled move from ``p0_rad`` (at ``t0_us``) to ``goal_rad``."""

    t0_us: int
    p0_rad: float
    goal_rad: float
    v0_rad_s: float = 0.0
    vmax_rad_s: float = math.inf
    accel_rad_s2: float = math.inf

    def __post_init__(self) -> None:
        d = self.goal_rad - self.p0_rad
        self._dir = 1.0 if d >= 0 else -1.0
        dist = abs(d)
        a, vmax = self.accel_rad_s2, self.vmax_rad_s
        u = max(0.0, min(self.v0_rad_s * self._dir, vmax))
        if math.isfinite(a):
            u = min(u, math.sqrt(2.0 * a * dist))
            peak = min(vmax, math.sqrt(a * dist + 0.5 * u * u))
            t1 = (peak - u) / a
            d1 = (peak * peak - u * u) / (2.0 * a)
            t3 = peak / a
            d3 = peak * peak / (2.0 * a)
        else:
            peak, t1, d1, t3, d3 = vmax, 0.0, 0.0, 0.0, 0.0
        if math.isinf(peak):       # no velocity and no acceleration limit: a step
            self._u, self._peak, self._a = 0.0, 0.0, a
            self._t = (0.0, 0.0, 0.0)
            self._d = (0.0, dist, 0.0)
            return
        d2 = max(0.0, dist - d1 - d3)
        self._u, self._peak, self._a = u, peak, a
        self._t = (t1, d2 / peak if peak > 0 else 0.0, t3)
        self._d = (d1, d2, d3)

    @property
    def duration_s(self) -> float:
        return sum(self._t)

    def at(self, t_us: int) -> tuple[float, float]:
        """(position_rad, velocity_rad_s) of the trajectory at ``t_us``."""
        t = max(0.0, (t_us - self.t0_us) * 1e-6)
        (t1, t2, t3), (d1, d2, _) = self._t, self._d
        u, peak, a, s = self._u, self._peak, self._a, self._dir
        if t >= t1 + t2 + t3:
            return self.goal_rad, 0.0
        if t < t1:
            return self.p0_rad + s * (u * t + 0.5 * a * t * t), s * (u + a * t)
        if t < t1 + t2:
            return self.p0_rad + s * (d1 + peak * (t - t1)), s * peak
        tau = t - t1 - t2
        return self.p0_rad + s * (d1 + d2 + peak * tau - 0.5 * a * tau * tau), s * (peak - a * tau)
