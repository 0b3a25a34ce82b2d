"""Sec. II-I feedback linearisation (Eq. 9) every 2 ms with the paper's saturation, and Eq. 11.

u = M (q_d'' - K_d (q' - q_d') - K_p (q - q_d)) - F(q), with M = diag(M, I1, I2) on
q = (x, roll, pitch) and F(q) the model's beam-contact + gravity generalised forces
(Eq. 1-4 with the *estimated* beam properties). The gains sit inside M so the error obeys
e'' + K_d e' + K_p e = 0 while no limit is hit.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hexhil.hil.world.beam_body import PAPER_BODY, BeamParams, BodyGeometry
from hexhil.hil.world.beams import external_forces, saturate
from hexhil.papers.beam_traversal.planner import Plan

KP_1_S2 = 100.0             # critically damped, natural frequency 10 rad/s
KD_1_S = 20.0


@dataclass
class FeedbackLinearisation:
    plan: Plan
    t0_us: int
    model_beams: list[BeamParams]
    geometry: BodyGeometry = PAPER_BODY
    kp: float = KP_1_S2
    kd: float = KD_1_S
    _theta: list[float] = field(default_factory=lambda: [0.0, 0.0])

    def __call__(self, t_us: int, q: tuple[float, float, float], qd: tuple[float, float, float]
                 ) -> tuple[float, float, float]:
        """(F_x, tau1, tau2), saturated to |F_x| <= 2 N, |tau| <= 0.1 N m."""
        g = self.geometry
        qdes, qd_des, qdd_des = self.plan.desired((t_us - self.t0_us) * 1e-6)
        e = np.asarray(q) - qdes
        ed = np.asarray(qd) - qd_des
        acc = qdd_des - self.kd * ed - self.kp * e
        ext = external_forces(g, self.model_beams, *q, self._theta)
        self._theta = list(ext.theta_rad)
        m = (g.mass_kg, g.inertia_kg_m2[0], g.inertia_kg_m2[1])
        return saturate(m[0] * acc[0] - ext.q_x_n, m[1] * acc[1] - ext.q_roll_nm, m[2] * acc[2] - ext.q_pitch_nm)
