"""Seed 000's beam traversal world: an ellipsoid body pushed through two torsion-spring plates.

Everything follows Xuan, Wang & Li, "Environmental force sensing enables robots to traverse
cluttered obstacles with interaction" (``/work/shared/seeds/000_*.txt``):

* body and beams (Sec. II-A, Eq. 12): hil/world/beam_body.py; DOF x, roll, pitch (yaw 0;
  R = Ry(pitch) Rx(roll), the Z-Y'-X' Tait-Bryan convention);
* contact (Eq. 4-5): hil/world/beam_contact.py;
* dynamics (Eq. 1-3) integrated at dt = 0.2 ms (semi-implicit Euler) in integer microseconds;
* force sensor (Eq. 6): F1 + F2 at 100 Hz with multiplicative Gaussian noise per axis.

Generalised forces: roll is driven by the moment about the body's major axis e1 (Eq. 1);
pitch by the moment about the world y axis, the axis the pitch angle rotates about. This is
the paper's e2 at zero roll and keeps the dynamics exactly the gradient of Eq. 8's landscape.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from hexhil.hil.world.beam_body import G_M_S2, PAPER_BODY, BeamParams, BodyGeometry, beam_torque_nm
from hexhil.hil.world.beam_contact import contact

DT_US = 200                 # Sec. II-B: time step 0.0002 s
SENSOR_PERIOD_US = 10_000   # Sec. II-D: 100 Hz force sensor
FX_MAX_N = 2.0              # Sec. II-I: |F_x| <= 2 N
TAU_MAX_NM = 0.1            # Sec. II-I: |tau_1|, |tau_2| <= 0.1 N m


@dataclass
class BodyState:
    x_m: float = -0.11
    vx_m_s: float = 0.05            # Sec. II-A: steady 0.05 m/s before the collision
    roll_rad: float = 0.0
    roll_rate_rad_s: float = 0.0
    pitch_rad: float = 0.0
    pitch_rate_rad_s: float = 0.0

    def q(self) -> tuple[float, float, float]:
        return self.x_m, self.roll_rad, self.pitch_rad

    def qd(self) -> tuple[float, float, float]:
        return self.vx_m_s, self.roll_rate_rad_s, self.pitch_rate_rad_s


@dataclass
class ExternalForces:
    """Beam contact + gravity, as generalised forces on (x, roll, pitch) and the sensed force."""

    q_x_n: float
    q_roll_nm: float
    q_pitch_nm: float
    contact_n: tuple[float, float, float]
    theta_rad: tuple[float, float]


def external_forces(g: BodyGeometry, beams: list[BeamParams], x: float, roll: float, pitch: float,
                    theta_prev: list[float] | None = None) -> ExternalForces:
    """Eq. 1-5: contact forces from each beam's torque balance, plus gravity (world frame).

    ``theta_prev``: the beams' deflections a step earlier (a plate under the body stays there,
    see ``beam_contact.contact``); none means upright beams.
    """
    mg = g.mass_kg * G_M_S2
    sa, ca, sb, cb = math.sin(roll), math.cos(roll), math.sin(pitch), math.cos(pitch)
    qx, qr, qp = 0.0, -mg * g.hc_m * sa * cb, -mg * g.hc_m * ca * sb
    fx = fy = fz = 0.0
    thetas = []
    e1 = (cb, 0.0, -sb)
    for i, bp in enumerate(beams):
        th, r, n, lever = contact(g, x, roll, pitch, bp.hb_m, i, theta_prev[i] if theta_prev else 0.0)
        thetas.append(th)
        if th == 0.0:
            continue
        mag = beam_torque_nm(th, bp.k_nm_per_rad, bp.preload_nm, bp.mass_kg, g.beam_length_m) / lever
        Fx, Fy, Fz = mag * n[0], mag * n[1], mag * n[2]
        fx, fy, fz = fx + Fx, fy + Fy, fz + Fz
        mx = r[1] * Fz - r[2] * Fy
        my = r[2] * Fx - r[0] * Fz
        mz = r[0] * Fy - r[1] * Fx
        qr += mx * e1[0] + my * e1[1] + mz * e1[2]
        qp += my
    thetas += [0.0] * (2 - len(thetas))    # a model without beams (the avoidance baseline)
    return ExternalForces(fx, qr, qp, (fx, fy, fz), (thetas[0], thetas[1]))


def saturate(fx_n: float, tau1_nm: float, tau2_nm: float) -> tuple[float, float, float]:
    """Sec. II-I actuator limits."""
    return (max(-FX_MAX_N, min(FX_MAX_N, fx_n)), max(-TAU_MAX_NM, min(TAU_MAX_NM, tau1_nm)),
            max(-TAU_MAX_NM, min(TAU_MAX_NM, tau2_nm)))


@dataclass
class BeamsWorld:
    """The simulated robot and beams, stepped in integer microseconds (lockstep, no wall clock)."""

    beams: list[BeamParams]
    geometry: BodyGeometry = PAPER_BODY
    state: BodyState = field(default_factory=BodyState)
    noise: float = 0.0
    seed: int = 0
    t_us: int = 0
    first_contact_us: int | None = None

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(self.seed)
        self._cmd = (0.0, 0.0, 0.0)
        self._theta = [0.0, 0.0]
        self.last = external_forces(self.geometry, self.beams, *self.state.q())
        self.free_run = True        # Sec. II-A: no force before contact, steady 0.05 m/s

    def command(self, fx_n: float, tau1_nm: float, tau2_nm: float) -> tuple[float, float, float]:
        """Apply an actuator command, saturated to the paper's limits; returns what was applied."""
        self._cmd = saturate(fx_n, tau1_nm, tau2_nm)
        return self._cmd

    @property
    def applied(self) -> tuple[float, float, float]:
        return self._cmd

    def step(self) -> None:
        """One Eq. 1-3 step of DT_US (semi-implicit Euler)."""
        g, s = self.geometry, self.state
        ext = self.last
        dt = DT_US * 1e-6
        if self.free_run and (ext.theta_rad[0] > 0 or ext.theta_rad[1] > 0):
            self.free_run = False
            self.first_contact_us = self.t_us
        if not self.free_run:
            fx, t1, t2 = self._cmd
            s.vx_m_s += dt * (fx + ext.q_x_n) / g.mass_kg
            s.roll_rate_rad_s += dt * (t1 + ext.q_roll_nm) / g.inertia_kg_m2[0]
            s.pitch_rate_rad_s += dt * (t2 + ext.q_pitch_nm) / g.inertia_kg_m2[1]
        s.x_m += dt * s.vx_m_s
        s.roll_rad += dt * s.roll_rate_rad_s
        s.pitch_rad += dt * s.pitch_rate_rad_s
        self.t_us += DT_US
        self.last = external_forces(g, self.beams, s.x_m, s.roll_rad, s.pitch_rad, self._theta)
        self._theta = list(self.last.theta_rad)

    def sense_force(self) -> tuple[float, float, float]:
        """Eq. 6: F1 + F2 with multiplicative Gaussian noise, one N(0, sigma) draw per axis."""
        z = self._rng.standard_normal(3) * self.noise
        f = self.last.contact_n
        return f[0] * (1 + z[0]), f[1] * (1 + z[1]), f[2] * (1 + z[2])

    def sample_after_contact(self, window_us: float, drive: Callable[[], None],
                             max_us: int) -> tuple[np.ndarray, np.ndarray]:
        """Sec. II-E: (poses, sensed forces) at 100 Hz from first contact for ``window_us``,
        or until the body flips; ``drive`` runs before each step (the propulsion)."""
        poses, forces = [], []
        while self.t_us < max_us:
            drive()
            self.step()
            if self.t_us % SENSOR_PERIOD_US == 0 and self.first_contact_us is not None:
                if self.t_us - self.first_contact_us > window_us or self.flipped:
                    break
                poses.append(self.state.q())
                forces.append(self.sense_force())
        return np.array(poses), np.array(forces)

    @property
    def flipped(self) -> bool:
        return abs(self.state.roll_rad) >= math.pi / 2 or abs(self.state.pitch_rad) >= math.pi / 2

    def passed(self, x_goal_m: float = 0.12) -> bool:
        """Past the beams: the level body's tail has reached the hinge line, without flipping."""
        return self.state.x_m >= x_goal_m and not self.flipped
