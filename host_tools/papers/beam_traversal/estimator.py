"""Beam-property estimation from the force samples of the sensing window (Sec. II-E, Eq. 7).

Both estimators fit k1, k2, h_b1, h_b2 to forces sensed at known body poses (the robot knows
its own pose; it reads ``body_pose`` frames beside ``force`` frames):

* ``paper``: Eq. 7's error (sum of force-vector distances) minimised by Nelder-Mead from 100
  random starts, k in [0, 5] N m/rad and h_b in [0, 5] mm (the paper's fminsearch set-up);
* ``fast`` (default): maximum likelihood under Eq. 6's noise. Each sensed component is
  F (1 + Z), Z ~ N(0, sigma): Gaussian with a standard deviation proportional to the model
  force, so the likelihood has a log-variance term (sum log|F|) besides the relative misfit;
  sigma is unknown and profiled out. The problem's structure makes it cheap: the unit force
  (force per unit k, Eq. 4-5) is one contact solve per h_b and varies smoothly with h_b, so it
  is interpolated by a polynomial in h_b from 5 solves (both beams at once, by symmetry); for
  fixed h_b the force is linear in k, so iteratively reweighted least squares gives k on a
  grid over h_b; the best cell then seeds a projected-Newton fit of all unknowns within the
  paper's ranges (k in [0, 5] N m/rad, h_b in [0, 5] mm). About 6 ms for 4 unknowns.

Unknowns: 4 = (k1, k2, h_b1, h_b2); 3 = h_b1 = h_b2 (Table 2); 2 = h_b1 = h_b2 = 0 (Table 3).
``cramer_rao_sd`` gives the bound no unbiased estimator can beat on the same samples.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from hexhil.hil.world.beam_body import G_M_S2, PAPER_BODY, BodyGeometry
from hexhil.hil.world.beam_contact import unit_contact_forces

HB_MAX_M = 0.005        # Sec. II-E: h_b guesses in [0, 5] mm
K_MAX_NM_PER_RAD = 5.0  # Sec. II-E: k guesses in [0, 5] N m/rad
RESTARTS = 100          # Sec. II-E: 100 random initial guesses
FORCE_FLOOR_N = 1e-3    # force frame resolution (1 mN): below it Eq. 6's proportional noise is not resolved
HB_DEGREE = 4           # unit force as a polynomial in h_b: interpolation error ~1e-7 over [0, 5] mm
HB_GRID = 21            # starting grid over [0, 5] mm (0.25 mm)
_MISFIT_FLOOR = 1e-12   # relative misfit^2 a component can resolve (interpolation): keeps noise-free fits finite


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


def _hb_bases(poses: np.ndarray, geometry: BodyGeometry, fixed_hb: bool) -> tuple[np.ndarray, np.ndarray]:
    """Both beams' unit forces as polynomials in u = h_b / 5 mm: coefficients (degree + 1, 3N) each.

    Chebyshev nodes on [0, 5] mm; with ``fixed_hb`` (2 unknowns) the constant h_b = 0. Beam 2 is
    beam 1 mirrored in y, i.e. beam 1 at the opposite roll with the force's y negated, so one
    contact solve over twice the poses serves both.
    """
    n = 1 if fixed_hb else HB_DEGREE + 1
    u = np.zeros(1) if fixed_hb else np.sort(0.5 * (1.0 - np.cos(np.pi * (np.arange(n) + 0.5) / n)))
    mirror = np.array([1.0, -1.0, 1.0])
    g = unit_forces(np.concatenate([poses, poses * mirror]), u * HB_MAX_M, 0, geometry)
    m = len(poses)
    g1, g2 = g[:, :m].reshape(n, -1), (g[:, m:] * mirror).reshape(n, -1)
    if fixed_hb:
        return g1, g2
    v = np.vander(u, n, increasing=True)
    return np.linalg.solve(v, g1), np.linalg.solve(v, g2)


def _poly(c: np.ndarray, u) -> np.ndarray:
    return (np.asarray(u, float)[..., None] ** np.arange(c.shape[0])) @ c


def _dpoly(c: np.ndarray, u) -> np.ndarray:
    n = c.shape[0]
    return (np.arange(1, n) * np.asarray(u, float)[..., None] ** np.arange(n - 1)) @ c[1:]


def _nll(F: np.ndarray, s: np.ndarray, floor_n: float) -> np.ndarray:
    """Eq. 6 negative log-likelihood with sigma profiled out (up to a constant), last axis summed.

    A component is N(F, sigma^2 (F^2 + floor^2)): -log L = 1/2 sum log v + N log sigma
    + sum (s - F)^2 / (2 sigma^2 v); at the best sigma that is 1/2 sum log v + N/2 log sum (s - F)^2 / v.
    """
    v = F * F + floor_n * floor_n
    r = s - F
    n = s.shape[-1]
    return 0.5 * np.log(v).sum(-1) + 0.5 * n * np.log((r * r / v).sum(-1) + n * _MISFIT_FLOOR)


def _irls_k(g1: np.ndarray, g2: np.ndarray, s: np.ndarray, floor_n: float, iterations: int = 3):
    """(k1, k2, model force) for each pair of unit-force fields (broadcast): least squares
    reweighted by 1 / F^2 (Eq. 6's variance), k clipped to [0, 5]; a beam that never touches
    gets k = 0 (the tiny ridge)."""
    w = np.ones_like(s)
    for _ in range(iterations):
        a11, a22, a12 = (w * g1 * g1).sum(-1), (w * g2 * g2).sum(-1), (w * g1 * g2).sum(-1)
        b1, b2 = (w * g1 * s).sum(-1), (w * g2 * s).sum(-1)
        ridge = 1e-12 * (a11 + a22) + 1e-300
        a11, a22 = a11 + ridge, a22 + ridge
        det = a11 * a22 - a12 * a12
        k1 = np.clip((a22 * b1 - a12 * b2) / det, 0.0, K_MAX_NM_PER_RAD)
        k2 = np.clip((a11 * b2 - a12 * b1) / det, 0.0, K_MAX_NM_PER_RAD)
        F = k1[..., None] * g1 + k2[..., None] * g2
        w = 1.0 / (F * F + floor_n * floor_n)
    return k1, k2, F


def _newton_in_box(fun_grad, x0: np.ndarray, lo: np.ndarray, hi: np.ndarray, iterations: int = 60,
                   step: float = 1e-7) -> np.ndarray:
    """Minimise a smooth function of a few bounded unknowns by projected Newton (Bertsekas).

    The Hessian is forward differences of the analytic gradient, its eigenvalues taken in
    absolute value (so a saddle is left downhill); unknowns at a bound with the gradient
    pushing outwards are held; Armijo backtracking along the projected step. Plain numpy on
    4 x 4 matrices: no threaded BLAS (scipy's L-BFGS-B left OpenBLAS workers spinning on a
    shared core).
    """
    x = np.clip(x0, lo, hi)
    f, g = fun_grad(x)
    for _ in range(iterations):
        h = step * np.maximum(1.0, np.abs(x))
        hess = np.array([(fun_grad(x + h[i] * np.eye(x.size)[i])[1] - g) / h[i] for i in range(x.size)])
        hess = 0.5 * (hess + hess.T)
        free = ~(((x <= lo) & (g > 0)) | ((x >= hi) & (g < 0)))
        d = np.zeros_like(x)
        if free.any():
            w, v = np.linalg.eigh(hess[np.ix_(free, free)])
            w = np.maximum(np.abs(w), 1e-10 * np.abs(w).max() + 1e-300)
            d[free] = -v @ ((v.T @ g[free]) / w)
        t = 1.0
        while True:
            x_new = np.clip(x + t * d, lo, hi)
            f_new, g_new = fun_grad(x_new)
            if f_new <= f + 1e-4 * g @ (x_new - x) or t < 1e-12:
                break
            t *= 0.5
        done = f_new > f or np.abs(x_new - x).max() < 1e-12
        if f_new <= f:
            x, f, g = x_new, f_new, g_new
        if done:
            break
    return x


def estimate_fast(poses: np.ndarray, forces: np.ndarray, unknowns: int = 4,
                  geometry: BodyGeometry = PAPER_BODY, floor_n: float = FORCE_FLOOR_N) -> Estimate:
    """Bounded maximum likelihood under Eq. 6 (see the module docstring).

    Components sensed as exactly 0 are left out: Eq. 6 reads 0 only where the force is 0, and
    they say nothing about k or h_b.
    """
    t0 = time.perf_counter()
    poses, forces = np.asarray(poses, float), np.asarray(forces, float)
    s_all = forces.reshape(-1)
    keep = s_all != 0.0
    if not keep.any():
        raise ValueError("no contact force in the samples")
    s, n = s_all[keep], int(keep.sum())
    nu = {4: 2, 3: 1, 2: 0}[unknowns]           # how many h_b unknowns
    c1_all, c2_all = _hb_bases(poses, geometry, nu == 0)
    c1, c2 = c1_all[:, keep], c2_all[:, keep]
    grid = np.linspace(0.0, 1.0, HB_GRID) if nu else np.zeros(1)
    u1, u2 = np.meshgrid(grid, grid, indexing="ij") if nu == 2 else (grid, grid)
    k1, k2, F = _irls_k(_poly(c1, u1), _poly(c2, u2), s, floor_n)
    cell = np.unravel_index(int(np.argmin(_nll(F, s, floor_n))), k1.shape)
    x0 = np.array([k1[cell], k2[cell], u1[cell], u2[cell]][:2 + nu])

    def split(x):
        return x[0], x[1], (x[2] if nu else 0.0), (x[3] if nu == 2 else (x[2] if nu else 0.0))

    def nll_and_grad(x):
        a, b, ua, ub = split(x)
        g1, g2 = _poly(c1, ua), _poly(c2, ub)
        F = a * g1 + b * g2
        v = F * F + floor_n * floor_n
        r = s - F
        S = (r * r / v).sum() + n * _MISFIT_FLOOR
        dF = F / v - (n / S) * (r / v + r * r * F / (v * v))     # d(-log L) / dF
        grad = [dF @ g1, dF @ g2]
        if nu == 1:
            grad.append(dF @ (a * _dpoly(c1, ua) + b * _dpoly(c2, ub)))
        elif nu == 2:
            grad += [a * (dF @ _dpoly(c1, ua)), b * (dF @ _dpoly(c2, ub))]
        return 0.5 * np.log(v).sum() + 0.5 * n * np.log(S), np.array(grad)

    lo = np.zeros(x0.size)
    hi = np.array([K_MAX_NM_PER_RAD] * 2 + [1.0] * nu)
    x = _newton_in_box(nll_and_grad, x0, lo, hi)
    a, b, ua, ub = split(x)
    model = (a * _poly(c1_all, ua) + b * _poly(c2_all, ub)).reshape(forces.shape)
    return Estimate(float(a), float(b), float(ua * HB_MAX_M), float(ub * HB_MAX_M),
                    float(eq7_error(model, forces)), time.perf_counter() - t0, "fast")


def cramer_rao_sd(poses: np.ndarray, k1: float, k2: float, hb1_m: float, hb2_m: float, noise: float,
                  unknowns: int = 4, geometry: BodyGeometry = PAPER_BODY, sigma_known: bool = True,
                  dh_m: float = 1e-6) -> np.ndarray:
    """Cramer-Rao bound under Eq. 6: the least standard deviations of (k1, k2[, h_b1[, h_b2]])
    (N m/rad, m) any unbiased estimator can reach from these poses' noisy forces.

    A component is N(F, sigma^2 F^2), so its Fisher information is (1/sigma^2 + 2) grad(log|F|)
    grad(log|F|)^T: the mean and the variance terms share one direction. With sigma unknown
    (``sigma_known=False``) it is a nuisance parameter and the bound is the Schur complement.
    Components with F = 0 are sensed exactly and left out. h_b derivatives: central differences.
    """
    poses = np.asarray(poses, float)
    h = np.array([[hb1_m - dh_m, hb1_m, hb1_m + dh_m], [hb2_m - dh_m, hb2_m, hb2_m + dh_m]])
    g1, g2 = unit_forces(poses, h[0], 0, geometry), unit_forces(poses, h[1], 1, geometry)
    F = (k1 * g1[1] + k2 * g2[1]).reshape(-1)
    cols = [g1[1].reshape(-1), g2[1].reshape(-1),
            (k1 * (g1[2] - g1[0]) / (2 * dh_m)).reshape(-1), (k2 * (g2[2] - g2[0]) / (2 * dh_m)).reshape(-1)]
    if unknowns == 3:
        cols = cols[:2] + [cols[2] + cols[3]]
    elif unknowns == 2:
        cols = cols[:2]
    on = F != 0.0
    d_log = np.stack(cols, axis=1)[on] / F[on, None]
    info = (1.0 / noise ** 2 + 2.0) * d_log.T @ d_log
    if not sigma_known:                         # sigma's row: 2 N / sigma^2, cross terms (2 / sigma) sum d_log
        cross = (2.0 / noise) * d_log.sum(0)
        info = info - np.outer(cross, cross) / (2.0 * on.sum() / noise ** 2)
    return np.sqrt(np.diag(np.linalg.inv(info)))


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
