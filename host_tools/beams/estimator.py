"""Beam-property estimation from the force samples of the sensing window (Sec. II-E, Eq. 7).

Both estimators fit k1, k2, h_b1, h_b2 to forces sensed at known body poses (the robot knows
its own pose; it reads ``body_pose`` frames beside ``force`` frames):

* ``paper``: Eq. 7's error (sum of force-vector distances) minimised by Nelder-Mead from 100
  random starts, k in [0, 5] N m/rad and h_b in [0, 5] mm (the paper's fminsearch set-up);
* ``fast`` (default): for fixed geometry (poses and h_b) the contact force is linear in k
  (Eq. 4: k theta = |F| lever), so k has a least-squares closed form for each h_b; what is
  left is a 0-, 1- or 2-D search over h_b in [0, 5] mm: a grid, then a finer grid around
  the best cell, weighted for Eq. 6's force-proportional noise.

Unknowns: 4 = (k1, k2, h_b1, h_b2); 3 = h_b1 = h_b2 (Table 2); 2 = h_b1 = h_b2 = 0 (Table 3).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from hil.world.beams import G_M_S2, PAPER_BODY, BodyGeometry, unit_contact_forces

HB_MAX_M = 0.005        # Sec. II-E: h_b guesses in [0, 5] mm
K_MAX_NM_PER_RAD = 5.0  # Sec. II-E: k guesses in [0, 5] N m/rad
RESTARTS = 100          # Sec. II-E: 100 random initial guesses


@dataclass
class Estimate:
    k1: float
    k2: float
    hb1_m: float
    hb2_m: float
    error_n: float          # Eq. 7 at the estimate
    elapsed_s: float
    method: str

    def as_dict(self) -> dict:
        return {"k1": self.k1, "k2": self.k2, "hb1_mm": self.hb1_m * 1e3, "hb2_mm": self.hb2_m * 1e3,
                "error_n": self.error_n, "elapsed_s": self.elapsed_s, "method": self.method}


def unit_forces(poses: np.ndarray, hb_m: np.ndarray, beam: int, geometry: BodyGeometry) -> np.ndarray:
    """Contact force per unit stiffness, shape (len(hb), N, 3): F_i = k_i * this (Eq. 4-5)."""
    x, roll, pitch = (poses[:, j][None, :] for j in range(3))
    theta, lever, normal = unit_contact_forces(x, roll, pitch, np.asarray(hb_m, float)[:, None], beam, geometry)
    return np.moveaxis(normal * (theta / lever), 0, -1)


def eq7_error(model: np.ndarray, sensed: np.ndarray) -> np.ndarray:
    """Eq. 7: sum over samples of |F_sensed - F| (last two axes: samples, xyz)."""
    return np.linalg.norm(model - sensed, axis=-1).sum(-1)


def _ls_k(g1: np.ndarray, g2: np.ndarray, f: np.ndarray, w: np.ndarray | float = 1.0
          ) -> tuple[np.ndarray, np.ndarray]:
    """Weighted least-squares (k1, k2) >= 0 for every pair of unit-force fields (broadcast)."""
    a11 = (w * g1 * g1).sum((-1, -2))
    a22 = (w * g2 * g2).sum((-1, -2))
    a12 = (w * g1 * g2).sum((-1, -2))
    b1 = (w * g1 * f).sum((-1, -2))
    b2 = (w * g2 * f).sum((-1, -2))
    det = a11 * a22 - a12 * a12
    with np.errstate(divide="ignore", invalid="ignore"):
        k1 = np.where(det > 1e-18, (a22 * b1 - a12 * b2) / det, 0.0)
        k2 = np.where(det > 1e-18, (a11 * b2 - a12 * b1) / det, 0.0)
        only1 = np.where(a11 > 0, np.maximum(b1 / a11, 0), 0.0)
        only2 = np.where(a22 > 0, np.maximum(b2 / a22, 0), 0.0)
    neg = (k1 < 0) | (k2 < 0)
    # constrained optimum on an edge: keep the better single-beam fit
    r1 = (w * (f - only1[..., None, None] * g1) ** 2).sum((-1, -2))
    r2 = (w * (f - only2[..., None, None] * g2) ** 2).sum((-1, -2))
    use1 = r1 <= r2
    k1 = np.where(neg, np.where(use1, only1, 0.0), k1)
    k2 = np.where(neg, np.where(use1, 0.0, only2), k2)
    return k1, k2


def _sse(g1, g2, k1, k2, f, w=1.0):
    return (w * (f - k1[..., None, None] * g1 - k2[..., None, None] * g2) ** 2).sum((-1, -2))


def _best_hb(poses, forces, geometry, range1, range2, n: int, tied: bool, w=1.0) -> tuple[float, float]:
    """The h_b pair (m) on an n-point grid (n x n, or the diagonal when tied) with least residual."""
    g_a = np.linspace(*range1, n)
    g_b = g_a if tied else np.linspace(*range2, n)
    g1 = unit_forces(poses, g_a, 0, geometry)
    g2 = unit_forces(poses, g_b, 1, geometry)
    if not tied:
        g1, g2 = g1[:, None], g2[None, :]
    k1, k2 = _ls_k(g1, g2, forces, w)
    cell = np.unravel_index(int(np.argmin(_sse(g1, g2, k1, k2, forces, w))), k1.shape)
    return (g_a[cell[0]], g_a[cell[0]]) if tied else (g_a[cell[0]], g_b[cell[1]])


def estimate_fast(poses: np.ndarray, forces: np.ndarray, unknowns: int = 4,
                  geometry: BodyGeometry = PAPER_BODY, coarse: int = 21, fine: int = 11) -> Estimate:
    """Closed-form k for each h_b, grid search over h_b (see the module docstring)."""
    t0 = time.perf_counter()
    poses, forces = np.asarray(poses, float), np.asarray(forces, float)
    h1 = h2 = 0.0
    tied = unknowns == 3
    step = HB_MAX_M / (coarse - 1)
    if unknowns in (3, 4):
        full = (0.0, HB_MAX_M)
        h1, h2 = _best_hb(poses, forces, geometry, full, full, coarse, tied)
    # Eq. 6 noise is proportional to the force, so the efficient fit weights each force
    # component by 1 / (its model value)^2: a second pass around the first answer does that.
    g1 = unit_forces(poses, np.array([h1]), 0, geometry)
    g2 = unit_forces(poses, np.array([h2]), 1, geometry)
    k1, k2 = _ls_k(g1, g2, forces)
    model = (k1[0] * g1[0] + k2[0] * g2[0])
    w = 1.0 / (model ** 2 + (0.02 * np.abs(model).max() + 1e-9) ** 2)
    if unknowns in (3, 4):
        near = [(max(h - step, 0.0), min(h + step, HB_MAX_M)) for h in (h1, h2)]
        h1, h2 = _best_hb(poses, forces, geometry, near[0], near[1], fine, tied, w)
        g1 = unit_forces(poses, np.array([h1]), 0, geometry)
        g2 = unit_forces(poses, np.array([h2]), 1, geometry)
    k1, k2 = _ls_k(g1, g2, forces, w)
    err = float(eq7_error(k1[0] * g1[0] + k2[0] * g2[0], forces))
    return Estimate(float(k1[0]), float(k2[0]), float(h1), float(h2), err, time.perf_counter() - t0, "fast")


def estimate_paper(poses: np.ndarray, forces: np.ndarray, unknowns: int = 4,
                   geometry: BodyGeometry = PAPER_BODY, restarts: int = RESTARTS, seed: int = 0) -> Estimate:
    """Sec. II-E: Eq. 7 minimised by Nelder-Mead (fminsearch tolerances) from random starts."""
    t0 = time.perf_counter()
    poses, forces = np.asarray(poses, float), np.asarray(forces, float)
    rng = np.random.default_rng(seed)

    def unpack(p):
        if unknowns == 4:
            return p[0], p[1], p[2] * 1e-3, p[3] * 1e-3
        if unknowns == 3:
            return p[0], p[1], p[2] * 1e-3, p[2] * 1e-3
        return p[0], p[1], 0.0, 0.0

    def err(p):
        k1, k2, h1, h2 = unpack(p)
        model = k1 * unit_forces(poses, np.array([h1]), 0, geometry)[0] + \
            k2 * unit_forces(poses, np.array([h2]), 1, geometry)[0]
        return float(eq7_error(model, forces))

    best = None
    n_h = {4: 2, 3: 1, 2: 0}[unknowns]
    for _ in range(restarts):
        x0 = np.concatenate([rng.uniform(0, K_MAX_NM_PER_RAD, 2), rng.uniform(0, HB_MAX_M * 1e3, n_h)])
        res = minimize(err, x0, method="Nelder-Mead",
                       options={"xatol": 1e-4, "fatol": 1e-4, "maxfev": 200 * len(x0)})
        if best is None or res.fun < best.fun:
            best = res
    k1, k2, h1, h2 = unpack(best.x)
    return Estimate(float(k1), float(k2), float(h1), float(h2), float(best.fun), time.perf_counter() - t0, "paper")


def estimate(poses, forces, unknowns: int = 4, method: str = "fast", geometry: BodyGeometry = PAPER_BODY,
             **kw) -> Estimate:
    if method == "paper":
        return estimate_paper(poses, forces, unknowns, geometry, **kw)
    return estimate_fast(poses, forces, unknowns, geometry, **kw)


@dataclass
class PreloadEstimate:
    """Sec. IV's two unknowns: one stiffness and one preload torque shared by both beams."""

    k: float                # N m/rad
    tau0_nm: float
    error_n: float          # Eq. 7 at the estimate
    elapsed_s: float

    def as_dict(self) -> dict:
        return {"k": self.k, "tau0_nm": self.tau0_nm, "error_n": self.error_n, "elapsed_s": self.elapsed_s}


def estimate_preloaded(poses: np.ndarray, forces: np.ndarray, hb_m: float = 0.0, beam_mass_kg: float = 0.0,
                       geometry: BodyGeometry = PAPER_BODY) -> PreloadEstimate:
    """Sec. IV (Eq. 12): k and tau_0 (equal for both beams) with h_b and M_B known.

    For fixed geometry each beam's force is (tau_0 + k theta - (L/2) M_B g sin theta) / lever
    along the inward normal: linear in (k, tau_0), so one least-squares solve gives both.
    """
    t0 = time.perf_counter()
    poses, forces = np.asarray(poses, float), np.asarray(forces, float)
    per_k = np.zeros_like(forces)
    per_tau0 = np.zeros_like(forces)
    weight = np.zeros_like(forces)
    for beam in (0, 1):
        theta, lever, normal = unit_contact_forces(poses[:, 0], poses[:, 1], poses[:, 2], hb_m, beam, geometry)
        n = normal.T                                    # (N, 3), zero where the beam is not touched
        per_k += n * (theta / lever)[:, None]
        per_tau0 += n / lever[:, None]
        weight += n * (0.5 * geometry.beam_length_m * beam_mass_kg * G_M_S2 * np.sin(theta) / lever)[:, None]
    a = np.stack([per_k.ravel(), per_tau0.ravel()], axis=1)
    (k, tau0), *_ = np.linalg.lstsq(a, (forces + weight).ravel(), rcond=None)
    err = float(eq7_error(k * per_k + tau0 * per_tau0 - weight, forces))
    return PreloadEstimate(float(k), float(tau0), err, time.perf_counter() - t0)
