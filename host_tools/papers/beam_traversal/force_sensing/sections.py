"""The sweeps behind each section of seed 000's results (Xuan, Wang & Li, Sec. III-IV), with
the paper's printed numbers they are compared with.

The noise in the estimation tables does not feed back into the push (F_x = 1 N, no control), so
each sensing window is simulated once without noise and Eq. 6 is applied per seed with the same
draws the world's sensor makes (tested against ``push_samples`` with that seed).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from hexhil.hil.world.beam_body import PAPER_BODY, BeamParams, BodyGeometry
from hexhil.hil.world.beams import SENSOR_PERIOD_US, BeamsWorld, BodyState
from hexhil.papers.beam_traversal.push import push_samples, start_after_delay
from hexhil.papers.beam_traversal import beams_run, estimator, landscape, planner

K_FLIMSY, K_STIFF = 0.01, 0.25            # Sec. III-A
K1_TRUE, K2_TRUE = 0.25, 0.27             # Sec. III-B
NOISES = (0.05, 0.10, 0.20, 0.50)         # Sec. II-D
SENSING_MS = (50, 100, 300, 600)          # Table 4
DELAYS_MS = (100, 300, 600)               # Sec. III-E
FX_SENSING_N = 1.0                        # Sec. III-B: "propelled by F_x = 1 N to encounter beams"
FX_GENTLE_N = 0.1                         # ours for Sec. III-D: 1 N carries flimsy beams over first
# Sec. III-E's series, as energy_runs keys them: (key prefix, label)
DELAY_SERIES = ((f"sensing/{K_STIFF}", f"stiff, {FX_SENSING_N:g} N"),
                (f"interact/{K_STIFF}", f"stiff, {FX_GENTLE_N:g} N"),
                (f"interact/{K_FLIMSY}", f"flimsy, {FX_GENTLE_N:g} N"))
HB_RANGE_M = 0.005                        # Sec. III-B: e_h = |h_b error| / 5 mm

# Tables 1-3 (relative errors, as printed): unknowns -> noise -> (e_k1, e_k2, e_h1[, e_h2])
PAPER_TABLES = {
    4: {0.05: (0.05, 0.05, 0.31, 0.28), 0.10: (0.09, 0.30, 0.67, 1.95),
        0.20: (0.01, 0.13, 0.28, 1.02), 0.50: (0.10, 0.27, 0.36, 1.37)},
    3: {0.05: (0.03, 0.03, 0.18), 0.10: (0.03, 0.03, 0.27), 0.20: (0.05, 0.04, 0.12), 0.50: (0.34, 0.33, 1.47)},
    2: {0.05: (0.0, 0.0), 0.10: (0.01, 0.01), 0.20: (0.02, 0.02), 0.50: (0.05, 0.05)},
}
# Table 4 (3 unknowns, sigma = 20 %): T_s ms -> (e_k1, e_k2, e_h), as printed
PAPER_TABLE4 = {50: (0.24, 0.63, 4.40), 100: (0.08, 0.08, 0.38), 300: (0.05, 0.04, 0.12), 600: (0.08, 0.07, 0.16)}
PAPER_NO_CONTROL = {(0.1, K_FLIMSY): "stuck", (0.1, K_STIFF): "stuck", (1.0, K_FLIMSY): "traversed",
                    (1.0, K_STIFF): "flipped"}
PAPER_ENERGY_MJ = {("interact", K_STIFF): 60, ("avoid", K_STIFF): 52, ("interact", K_FLIMSY): 21,
                   ("avoid", K_FLIMSY): 52}                  # Sec. III-D
PAPER_K0 = 0.028                                             # Sec. III-A

# Sec. IV robot: a = 0.19, b = 0.09, c = 0.035 m, 0.8 kg, CoM 3 mm below the centre; beams
# L = 0.305, w = 0.1 m, M_B = 0.16 kg, d = 0.15 m; k = 0.78 N m/rad, tau_0 = 0.19 N m; driven at
# 0.064 m/s. Assumed (not in the paper): uniform-density inertia, centre height H = 0.114 m
# (H / L = 0.375 as in the simulation model), h_b = 0, and the 20 % Eq. 6 noise of Sec. III-C.
ROBOT_K, ROBOT_TAU0_NM, ROBOT_MB_KG, ROBOT_SPEED_M_S = 0.78, 0.19, 0.16, 0.064
PAPER_ROBOT_ESTIMATE = (0.67, 0.21)
ROBOT_NOISE = 0.2
ROBOT_WINDOW_S = 3.0


def robot_geometry(centre_to_centre: bool) -> BodyGeometry:
    a, b, c, m = 0.19, 0.09, 0.035, 0.8
    inertia = (m * (b * b + c * c) / 5, m * (a * a + c * c) / 5, m * (a * a + b * b) / 5)
    return BodyGeometry(a_m=a, b_m=b, c_m=c, mass_kg=m, hc_m=0.003, inertia_kg_m2=inertia, height_m=0.114,
                        beam_width_m=0.1, beam_length_m=0.305, gap_m=0.15, gap_centre_to_centre=centre_to_centre)


def sensed(forces: np.ndarray, noise: float, seed: int) -> np.ndarray:
    """Eq. 6 on clean samples with BeamsWorld.sense_force's draws for ``seed`` (one N(0, 1) per axis)."""
    return forces * (1.0 + np.random.default_rng(seed).standard_normal(forces.shape) * noise)


def _rel_errors(est: estimator.Estimate, unknowns: int) -> tuple[float, ...]:
    e = (abs(est.k1 - K1_TRUE) / K1_TRUE, abs(est.k2 - K2_TRUE) / K2_TRUE)
    if unknowns == 4:
        return e + (est.hb1_m / HB_RANGE_M, est.hb2_m / HB_RANGE_M)
    return e + ((est.hb1_m / HB_RANGE_M,) if unknowns == 3 else ())


def _bound(poses: np.ndarray, noise: float, unknowns: int) -> tuple[float, ...]:
    """Cramer-Rao standard deviations (sigma unknown, as for both estimators) as relative errors."""
    sd = estimator.cramer_rao_sd(poses, K1_TRUE, K2_TRUE, 0.0, 0.0, noise, unknowns, sigma_known=False)
    return (sd[0] / K1_TRUE, sd[1] / K2_TRUE) + tuple(sd[2:] / HB_RANGE_M)


def estimation_tables(seeds: int) -> dict[str, Any]:
    """Tables 1-4: relative errors per seed of the fast estimator (true h_b = 0), and the
    Cramer-Rao bound of each cell."""
    clean = {ms: push_samples(K1_TRUE, K2_TRUE, 0.0, 0.0, 0.0, ms, 0) for ms in SENSING_MS}
    poses, forces = clean[300]
    tables: dict[str, Any] = {}
    bounds: dict[str, tuple[float, ...]] = {}
    for unknowns in (4, 3, 2):
        for noise in NOISES:
            errs = [_rel_errors(estimator.estimate(poses, sensed(forces, noise, s), unknowns), unknowns)
                    for s in range(seeds)]
            tables[f"{unknowns}/{noise}"] = np.array(errs)
            bounds[f"{unknowns}/{noise}"] = _bound(poses, noise, unknowns)
    for ms in SENSING_MS:
        p, f = clean[ms]
        tables[f"Ts/{ms}"] = np.array([_rel_errors(estimator.estimate(p, sensed(f, 0.2, s), 3), 3)
                                       for s in range(seeds)])
        bounds[f"Ts/{ms}"] = _bound(p, 0.2, 3)
    return {"errors": tables, "bounds": bounds, "fig3": (poses, forces)}


def no_control() -> list[dict[str, Any]]:
    """Sec. III-A: constant F_x, no torques."""
    out = []
    for fx in (0.1, 1.0):
        for k in (K_FLIMSY, K_STIFF):
            r = beams_run.run(beams_run.RunConfig(k, k, strategy="none", fx_n=fx))
            r["outcome"] = "traversed" if r["traversed"] else ("flipped" if r["flipped"] else "stuck")
            r["paper"] = PAPER_NO_CONTROL[(fx, k)]
            out.append(r)
    return out


def planning(grid: landscape.Grid, delay_ms: float = 300.0) -> dict[str, Any]:
    """k0, the landscape's crossover (from x = -0.1 m, level), the modes after the delay, and the
    least push that can carry the undamped body over each kind of beam (Sec. III-A's check)."""
    land = landscape.build(grid)
    plans = {k: planner.plan(land, k, k, start_after_delay(k, k, 0.0, delay_ms)) for k in (K_FLIMSY, K_STIFF)}
    contact = start_after_delay(K_FLIMSY, K_FLIMSY, 0.0, 0.0)      # the free run ends at first contact
    kinetic_j = 0.5 * PAPER_BODY.mass_kg * BodyState().vx_m_s ** 2
    return {"land": land, "plans": plans, "k0": PAPER_BODY.k0_nm_per_rad(),
            "crossover_k": planner.crossover_k(land, (-0.1, 0.0, 0.0), iterations=8),
            "contact": contact, "kinetic_j": kinetic_j,
            "critical_push_n": {k: planner.critical_push_n(land, k, k, contact, kinetic_j)
                                for k in (K_FLIMSY, K_STIFF)}}


def clear_gap_plans(grid: landscape.Grid) -> dict[str, Any]:
    """The other reading of d (clear gap 0.12 m), for the side-by-side figure."""
    land = landscape.build(grid, geometry=BodyGeometry(gap_centre_to_centre=False))
    return {"land": land, "plans": {k: planner.plan(land, k, k, (-0.1, 0.0, 0.0)) for k in (K_FLIMSY, K_STIFF)}}


def energy_runs(grid: landscape.Grid) -> dict[str, Any]:
    """Sec. III-D/E (20 % noise): interaction at each delay and the avoidance baseline with the gentle
    push until control starts, and stiff beams at each delay with Sec. III-B's 1 N push (``sensing/``).
    The paper states neither push; only the 1 N one pitches the body up more the longer the delay,
    as its Fig. 7A shows."""
    runs: dict[str, Any] = {}
    for k in (K_FLIMSY, K_STIFF):
        for d in DELAYS_MS:
            runs[f"interact/{k}/{d}"] = beams_run.run(beams_run.RunConfig(k, k, fx_n=FX_GENTLE_N, delay_ms=d,
                                                                              grid=grid))
        runs[f"avoid/{k}"] = beams_run.run(beams_run.RunConfig(k, k, strategy="avoid", fx_n=FX_GENTLE_N,
                                                                   grid=grid))
    for d in DELAYS_MS:
        runs[f"sensing/{K_STIFF}/{d}"] = beams_run.run(beams_run.RunConfig(K_STIFF, K_STIFF, fx_n=FX_SENSING_N,
                                                                               delay_ms=d, grid=grid))
    return runs


def robot_push(geometry: BodyGeometry, noise: float, seed: int) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Sec. IV: the rail drives the body at 0.064 m/s (its speed is reset every step); roll and
    pitch are passive. Samples from first contact for ROBOT_WINDOW_S or until the body flips."""
    beam = BeamParams(ROBOT_K, 0.0, ROBOT_TAU0_NM, ROBOT_MB_KG)
    w = BeamsWorld([beam, beam], geometry, BodyState(x_m=-0.22, vx_m_s=ROBOT_SPEED_M_S), noise=noise, seed=seed)

    def hold_speed() -> None:  # the rail holds the robot's speed
        w.state.vx_m_s = ROBOT_SPEED_M_S

    p, forces = w.sample_after_contact(ROBOT_WINDOW_S * 1e6, hold_speed, 20_000_000)
    info = {"samples": len(p), "flipped": w.flipped, "max_pitch_deg": float(np.degrees(np.abs(p[:, 2]).max())),
            "window_s": len(p) * SENSOR_PERIOD_US * 1e-6}
    return p, forces, info


def robot_validation(seeds: int) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for name, c2c in (("centre-to-centre", True), ("clear gap", False)):
        g = robot_geometry(c2c)
        p, f, info = robot_push(g, 0.0, 0)
        exact = estimator.estimate_preloaded(p, f, 0.0, ROBOT_MB_KG, g)
        noisy = np.array([[e.k, e.tau0_nm] for e in
                          (estimator.estimate_preloaded(p, sensed(f, ROBOT_NOISE, s), 0.0, ROBOT_MB_KG, g)
                           for s in range(seeds))])
        out[name] = {"info": info, "noise_free": exact.as_dict(), "noisy": noisy}
    return out
