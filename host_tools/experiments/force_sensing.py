"""Seed 000's results reproduced (Xuan, Wang & Li, ``/work/shared/seeds/000_*.txt``), ours beside the paper's.

Sections, in the paper's order (Sec. III-IV):

* no control (Sec. III-A, Fig. 5): F_x = 0.1 / 1 N into flimsy (k = 0.01) and stiff (0.25) beams;
* estimation (Sec. III-B, Tables 1-4): relative errors over noise seeds, fast estimator;
* planning (Sec. II-G/H, III-C): k0, the landscape's own crossover, planned modes;
* energy (Sec. III-D, Eq. 11): interaction vs the obstacle-avoidance baseline;
* sensory delay (Sec. III-E, Fig. 7): energy at 100 / 300 / 600 ms;
* robot validation (Sec. IV, Eq. 12): k and tau_0 from a prescribed-speed push.

Everything reuses hil/world/beams.py and host_tools/traversal/; this module only sweeps and reports.
The noise in the estimation tables does not feed back into the push (F_x = 1 N, no control), so
each sensing window is simulated once without noise and Eq. 6 is applied per seed with the same
draws the world's sensor makes (tested against ``push_samples`` with that seed).
"""
from __future__ import annotations

import argparse
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from hil.world.beams import (PAPER_BODY, SENSOR_PERIOD_US, BeamParams, BeamsWorld, BodyGeometry, BodyState)
from host_tools.traversal import closed_loop, estimator, landscape, planner
from host_tools.cli import emit
from host_tools.commands.beams import _start_after_delay, push_samples
from protocol.errors import UserError

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
VMAX_MJ = 60.0                            # landscape colour scale: barriers of interest are below this


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
            r = closed_loop.run(closed_loop.RunConfig(k, k, strategy="none", fx_n=fx))
            r["outcome"] = "traversed" if r["traversed"] else ("flipped" if r["flipped"] else "stuck")
            r["paper"] = PAPER_NO_CONTROL[(fx, k)]
            out.append(r)
    return out


def planning(grid: landscape.Grid, delay_ms: float = 300.0) -> dict[str, Any]:
    """k0, the landscape's crossover (from x = -0.1 m, level), the modes after the delay, and the
    least push that can carry the undamped body over each kind of beam (Sec. III-A's check)."""
    land = landscape.build(grid)
    plans = {k: planner.plan(land, k, k, _start_after_delay(k, k, 0.0, delay_ms)) for k in (K_FLIMSY, K_STIFF)}
    contact = _start_after_delay(K_FLIMSY, K_FLIMSY, 0.0, 0.0)      # the free run ends at first contact
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
            runs[f"interact/{k}/{d}"] = closed_loop.run(closed_loop.RunConfig(k, k, fx_n=FX_GENTLE_N, delay_ms=d,
                                                                              grid=grid))
        runs[f"avoid/{k}"] = closed_loop.run(closed_loop.RunConfig(k, k, strategy="avoid", fx_n=FX_GENTLE_N,
                                                                   grid=grid))
    for d in DELAYS_MS:
        runs[f"sensing/{K_STIFF}/{d}"] = closed_loop.run(closed_loop.RunConfig(K_STIFF, K_STIFF, fx_n=FX_SENSING_N,
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


# ----------------------------------------------------------------------------- figures
def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _save(fig: Any, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    _plt().close(fig)
    return path


def fig_noisy_forces(poses: np.ndarray, forces: np.ndarray, path: Path) -> Path:
    """Fig. 3: sensed contact force at 5/10/20/50 % noise (stiff beams, 1 N push, T_s = 300 ms)."""
    plt = _plt()
    t = np.arange(len(forces)) * SENSOR_PERIOD_US * 1e-3
    fig, axes = plt.subplots(1, 4, figsize=(14, 3.2), sharey=True)
    for ax, noise in zip(axes, NOISES):
        noisy = sensed(forces, noise, 0)
        for j, (lab, col) in enumerate(zip("xyz", ("C0", "C1", "C2"))):
            ax.plot(t, forces[:, j], color=col, lw=1)
            ax.plot(t, noisy[:, j], ".", color=col, ms=3, label=f"F{lab}")
        ax.set_title(f"noise {noise:.0%}")
        ax.set_xlabel("time after contact (ms)")
    axes[0].set_ylabel("contact force (N)")
    axes[0].legend()
    return _save(fig, path)


def fig_landscape(plan_res: dict[str, Any], path: Path) -> Path:
    """Fig. 4-like: Eq. 8 slices with the planned paths projected onto them."""
    plt = _plt()
    land = plan_res["land"]
    g = land.grid
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for ax, k, axis in ((axes[0], K_FLIMSY, 2), (axes[1], K_STIFF, 1)):
        e = land.energy(k, k)
        e = e - e.min()                  # above the level pose far from the beams
        p = plan_res["plans"][k]
        if axis == 2:       # pitch mode: the roll = 0 slice, E(x, pitch)
            sl, ang, lab = e[:, g.snap(0, 0, 0)[1], :], g.pitch_rad, "pitch (deg)"
        else:               # roll mode: the pitch = 0 slice, E(x, roll)
            sl, ang, lab = e[:, :, g.snap(0, 0, 0)[2]], g.roll_rad, "roll (deg)"
        im = ax.pcolormesh(g.x_m, np.degrees(ang), sl.T * 1e3, shading="auto", cmap="viridis", vmax=VMAX_MJ)
        ax.plot(p.path[:, 0], np.degrees(p.path[:, axis]), "w-", lw=2, label=f"planned path ({p.mode})")
        ax.set_title(f"k = {k} N m/rad: E at {'roll' if axis == 2 else 'pitch'} = 0")
        ax.set_xlabel("x (m)")
        ax.set_ylabel(lab)
        ax.legend(loc="lower left")
        fig.colorbar(im, ax=ax, label="E - E_min (mJ)")
    return _save(fig, path)


def fig_gap_readings(c2c: dict[str, Any], clear: dict[str, Any], path: Path) -> Path:
    """Both readings of d = 0.12 m: E(roll, pitch) at x = 0 with each k's planned path projected."""
    plt = _plt()
    fig, axes = plt.subplots(2, 2, figsize=(10, 8))
    for row, (name, res) in enumerate((("centre-to-centre (chosen)", c2c), ("clear gap", clear))):
        land = res["land"]
        g = land.grid
        ix = g.snap(0.0, 0, 0)[0]
        for col, k in enumerate((K_FLIMSY, K_STIFF)):
            ax = axes[row, col]
            full = land.energy(k, k)
            e = full[ix] - full.min()
            im = ax.pcolormesh(np.degrees(g.roll_rad), np.degrees(g.pitch_rad), e.T * 1e3, shading="auto",
                               cmap="viridis", vmax=VMAX_MJ)
            p = res["plans"][k]
            ax.plot(np.degrees(p.path[:, 1]), np.degrees(p.path[:, 2]), "w-", lw=2)
            ax.set_title(f"{name}, k = {k}: plans {p.mode}")
            ax.set_xlabel("roll (deg)")
            ax.set_ylabel("pitch (deg)")
            fig.colorbar(im, ax=ax, label="E - E_min at x = 0 (mJ)")
    return _save(fig, path)


def fig_delay(runs: dict[str, Any], path: Path) -> Path:
    """Fig. 7: (A) pitch at the start of control, (B) Eq. 11 energy, against the sensory delay."""
    plt = _plt()
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.8))
    for key, lab in DELAY_SERIES:
        rs = [runs[f"{key}/{d}"] for d in DELAYS_MS]
        a.plot(DELAYS_MS, [r.get("control_start", {}).get("pitch_deg", float("nan")) for r in rs], "o-", label=lab)
        b.plot(DELAYS_MS, [r["energy_J"] * 1e3 for r in rs], "o-", label=f"{lab} (interaction)")
    for k, lab in ((K_STIFF, "stiff"), (K_FLIMSY, "flimsy")):
        b.axhline(runs[f"avoid/{k}"]["energy_J"] * 1e3, ls="--", color="grey" if k == K_STIFF else "k",
                  label=f"{lab} avoidance")
    a.set_xlabel("sensory delay (ms)")
    a.set_ylabel("pitch at control start (deg)")
    a.legend()
    b.set_xlabel("sensory delay (ms)")
    b.set_ylabel("energy cost E_cost (mJ)")
    b.legend(fontsize=8)
    return _save(fig, path)


# ----------------------------------------------------------------------------- report
def _pct(x: float) -> str:
    return f"{100 * x:.1f}"


def _med_iqr(col: np.ndarray) -> str:
    q1, med, q3 = np.percentile(col, [25, 50, 75])
    return f"{_pct(med)} [{_pct(q1)}-{_pct(q3)}]"


def markdown(res: dict[str, Any], quick: bool, seeds: int, figs: dict[str, str]) -> str:
    g = res["grid"]
    lines = [
        "# Force sensing through grass-like beams (seed 000): ours beside the paper's", "",
        f"`hexhil experiment force-sensing{' --quick' if quick else ''}`: {seeds} noise seeds; landscape grid "
        f"{g['dx_mm']:g} mm / {g['dangle_deg']:g} deg ({g['states']:,} states); wall time {res['wall_s']:.0f} s.",
        "Relative errors in % as median [inter-quartile range] over the seeds; the paper's are single trials.",
        "", "## 1. No control (Sec. III-A, Fig. 5)", "",
        "| F_x (N) | k (N m/rad) | ours | paper | end time after contact (s) | max pitch (deg) |",
        "|---|---|---|---|---|---|"]
    for r in res["no_control"]:
        mark = "" if r["outcome"] == r["paper"] else " **(differs)**"
        lines.append(f"| {r['fx_n']} | {r['k1']} | {r['outcome']}{mark} | {r['paper']} | "
                     f"{r['t_end_s'] - (r['t_contact_s'] or 0):.2f} | {r['max_pitch_deg']:.0f} |")
    crit, contact = res["critical_push_n"], res["contact"]
    lines += ["", "Differences are reported, not tuned away. Quasi-static check (`planner.critical_push_n`): with "
              "no damping and no torques T + E - F_x x is conserved (Eq. 1-3, 8), so a constant push can carry "
              f"the body past the beams only if the contact state (x = {contact[0]:.3f} m, level, "
              f"{res['kinetic_j'] * 1e3:.2f} mJ kinetic) connects to the far side where E - F_x x stays below its "
              f"start value. Least such push on this grid: flimsy {crit[K_FLIMSY]:.3f} N, stiff "
              f"{crit[K_STIFF]:.2f} N. A 0.1 N push is above the flimsy value: along the landscape's valley the "
              f"flimsy beams resist with at most about {crit[K_FLIMSY]:.2f} N, so in the paper's own equations "
              "they cannot hold 0.1 N; the body stalls pitched up and creeps over (docs/beams.md).",
              "", "## 2. Estimation (Sec. III-B, Tables 1-4)", "",
              "Push with F_x = 1 N into k1 = 0.25, k2 = 0.27 N m/rad, h_b1 = h_b2 = 0; e_k = |k error| / k, "
              "e_h = |h_b error| / 5 mm. Fast estimator: maximum likelihood under Eq. 6, h_b and k bounded "
              "to the paper's ranges.", ""]
    names = {4: ("e_k1", "e_k2", "e_h1", "e_h2"), 3: ("e_k1", "e_k2", "e_h"), 2: ("e_k1", "e_k2")}
    for table, unknowns in ((1, 4), (2, 3), (3, 2)):
        lines += [f"**Table {table}: {unknowns} unknowns**", "",
                  "| noise | " + " | ".join(f"{n} ours | {n} paper" for n in names[unknowns]) + " |",
                  "|---|" + "---|---|" * len(names[unknowns])]
        for noise in NOISES:
            errs = res["estimation"]["errors"][f"{unknowns}/{noise}"]
            paper = PAPER_TABLES[unknowns][noise]
            cells = [f"{_med_iqr(errs[:, j])} | {_pct(paper[j])}" for j in range(len(paper))]
            lines.append(f"| {noise:.0%} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += ["**Table 4: 3 unknowns, noise 20 %, sensing time T_s** (the paper prints e_k1 = 24 % beside "
              "k1 = 0.090 at 50 ms, i.e. 64 %; copied as printed)", "",
              "| T_s (ms) | e_k1 ours | e_k1 paper | e_k2 ours | e_k2 paper | e_h ours | e_h paper |",
              "|---|---|---|---|---|---|---|"]
    for ms in SENSING_MS:
        errs = res["estimation"]["errors"][f"Ts/{ms}"]
        lines.append(f"| {ms} | " + " | ".join(f"{_med_iqr(errs[:, j])} | {_pct(PAPER_TABLE4[ms][j])}"
                                               for j in range(3)) + " |")
    lines += ["", "**Cramer-Rao bound** of each cell (Eq. 6 noise as the world's sensor draws it, sigma unknown as "
              "for both estimators): the least standard deviation of any unbiased estimator, in %, and in brackets "
              "the median |error| it implies (0.674 sd). True h_b = 0 sits on the paper's bound [0, 5] mm: a "
              "bounded estimator reads h_b = 0 for a good share of the seeds and then estimates k as with h_b "
              "known, so its medians can fall below the unbiased bound; none can beat the 2-unknown case "
              "(Table 3) without knowing h_b.", "",
              "| cell | e_k1 | e_k2 | e_h1 | e_h2 |", "|---|---|---|---|---|"]
    for key, sd in res["estimation"]["bounds"].items():
        kind, level = key.split("/")
        name = f"T_s {level} ms, 3 unknowns, 20 %" if kind == "Ts" else f"{kind} unknowns, {float(level):.0%}"
        cells = [f"{_pct(v)} ({_pct(0.674 * v)})" for v in sd] + [""] * (4 - len(sd))
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    lines += ["", f"Worse than the paper's single trial (our median above theirs): {res['worse'] or 'none'}.", "",
              f"![noisy forces, Fig. 3]({figs['noisy_forces']})", "",
              "## 3. Planning (Sec. II-G/H, III-C)", "",
              "| quantity | ours | paper |", "|---|---|---|",
              f"| k0 = M g h_c / arccos(H/L)^2 (N m/rad) | {res['k0']:.4f} | {PAPER_K0} |",
              f"| landscape's own pitch/roll crossover k (from x = -0.1 m, level) | {res['crossover_k']:.4f} | "
              "(not reported) |"]
    for k in (K_FLIMSY, K_STIFF):
        p = res["plans"][k]
        lines.append(f"| planned mode, k = {k} (start after 300 ms delay) | {p['mode']} (barrier "
                     f"{p['barrier_J'] * 1e3:.1f} mJ, path cost {p['path_cost_J'] * 1e3:.1f} mJ) | "
                     f"{'pitch' if k == K_FLIMSY else 'roll'} |")
    lines += ["", f"![landscape slices with the planned paths, Fig. 4]({figs['landscape']})", "",
              "Both readings of the gap width d = 0.12 m (docs/beams.md): E(roll, pitch) at x = 0 with each "
              "stiffness's planned path (from x = -0.1 m, level).", "",
              "| reading | k = 0.01 plans | k = 0.25 plans |", "|---|---|---|"]
    for name, key in (("centre-to-centre (chosen)", "c2c"), ("clear gap", "clear")):
        m = res["gap_modes"][key]
        lines.append(f"| {name} | {m[str(K_FLIMSY)]} | {m[str(K_STIFF)]} |")
    lines += ["", f"![both gap readings]({figs['gap_readings']})", "",
              "## 4. Energy with control vs avoidance (Sec. III-D, Eq. 11)", "",
              f"{FX_GENTLE_N:g} N push until control starts, 20 % noise, 3 unknowns, 300 ms delay, seed 0.", "",
              "| beams | strategy | ours: outcome, mode | ours E_cost (mJ) | paper E_cost (mJ) |",
              "|---|---|---|---|---|"]
    for k, lab in ((K_STIFF, "stiff"), (K_FLIMSY, "flimsy")):
        for strat, key in (("interact", f"interact/{k}/300"), ("avoid", f"avoid/{k}")):
            r = res["energy"][key]
            what = "traversed" if r["traversed"] else ("flipped" if r["flipped"] else "stuck")
            lines.append(f"| {lab} ({k}) | {strat} | {what}, {r['mode']} | {r['energy_J'] * 1e3:.1f} | "
                         f"{PAPER_ENERGY_MJ[(strat, k)]} |")
    lines += ["", "## 5. Sensory delay (Sec. III-E, Fig. 7)", "",
              "The push until control starts is not stated for Sec. III-E. With Sec. III-B's "
              f"{FX_SENSING_N:g} N (first row) the body pitches up more the longer the delay, as in the paper's "
              f"Fig. 7A; with our Sec. III-D {FX_GENTLE_N:g} N it hardly moves before control, so the plans and "
              f"energies barely change. Flimsy beams are not run at {FX_SENSING_N:g} N: that push carries the body "
              "over them before a 300 ms delay ends (the no-control result), leaving nothing to control.", "",
              "| beams, push | " + " | ".join(f"{d} ms: E (mJ), start pitch (deg)" for d in DELAYS_MS)
              + " | rises with delay? |",
              "|---|" + "---|" * len(DELAYS_MS) + "---|"]
    for key, lab in DELAY_SERIES:
        rs = [res["energy"][f"{key}/{d}"] for d in DELAYS_MS]
        es = [r["energy_J"] for r in rs]
        rises = all(b > a for a, b in zip(es, es[1:]))
        lines.append(f"| {lab} | " + " | ".join(
            f"{r['energy_J'] * 1e3:.1f}, {r.get('control_start', {}).get('pitch_deg', float('nan')):.1f}"
            + ("" if r["traversed"] else " (not traversed)") for r in rs) + f" | {'yes' if rises else '**no**'} |")
    lines += ["", "Paper: energy rises with the delay (Fig. 7B), all trials traverse.", "",
              f"![energy vs delay, Fig. 7]({figs['delay']})", "",
              "## 6. Robot validation variant (Sec. IV, Eq. 12)", "",
              f"Simulated rig: k = {ROBOT_K} N m/rad, tau_0 = {ROBOT_TAU0_NM} N m, M_B = {ROBOT_MB_KG} kg, body "
              "a/b/c = 0.19/0.09/0.035 m, 0.8 kg, CoM 3 mm low, beams L = 0.305, w = 0.1 m, d = 0.15 m, driven at "
              "0.064 m/s with passive roll/pitch. **Assumed** (not in the paper): centre height H = 0.114 m "
              "(H/L as in the simulation model), uniform-density inertia, h_b = 0 known, Eq. 6 noise "
              f"{ROBOT_NOISE:.0%}, both readings of d. Estimator: `estimator.estimate_preloaded` (Eq. 12 is "
              "linear in k and tau_0 for fixed geometry: one least-squares solve).", "",
              "| reading of d | samples (window s) | flipped in window | k noise-free | tau_0 noise-free | "
              f"k at {ROBOT_NOISE:.0%} (median [IQR]) | tau_0 at {ROBOT_NOISE:.0%} | paper k / tau_0 |",
              "|---|---|---|---|---|---|---|---|"]
    for name, r in res["robot"].items():
        nk, nt = r["noisy"][:, 0], r["noisy"][:, 1]
        q = lambda v: f"{np.median(v):.3f} [{np.percentile(v, 25):.3f}-{np.percentile(v, 75):.3f}]"  # noqa: E731
        lines.append(f"| {name} | {r['info']['samples']} ({r['info']['window_s']:.2f}) | {r['info']['flipped']} "
                     f"(max pitch {r['info']['max_pitch_deg']:.0f} deg) | {r['noise_free']['k']:.3f} | "
                     f"{r['noise_free']['tau0_nm']:.3f} | {q(nk)} | {q(nt)} | "
                     f"{PAPER_ROBOT_ESTIMATE[0]} / {PAPER_ROBOT_ESTIMATE[1]} (true 0.78 / 0.19) |")
    lines += ["", "The paper's 14 % / 11 % errors come from a physical rig (inertial force in the sensor, "
              "tracking error); ours are simulated with the model's own physics, so they measure only the "
              "estimator under sensor noise. With 3 mm of CoM offset the simulated body pitches up until it "
              "counts as flipped well inside the window; the samples until then are used.", ""]
    return "\n".join(lines)


def main(quick: bool, out: Path, seeds: int | None = None, grid: landscape.Grid | None = None) -> dict[str, Any]:
    """Run every section, write ``force-sensing.md`` and the PNGs into ``out``; returns the summary."""
    t0 = time.perf_counter()
    seeds = seeds or (5 if quick else 20)
    grid = grid or (landscape.paper_grid(0.004, 5) if quick else landscape.paper_grid())
    out.mkdir(parents=True, exist_ok=True)
    res: dict[str, Any] = {"grid": {"dx_mm": (grid.x_m[1] - grid.x_m[0]) * 1e3,
                                    "dangle_deg": math.degrees(grid.roll_rad[1] - grid.roll_rad[0]),
                                    "states": int(np.prod(grid.shape))}}
    res["no_control"] = no_control()
    est = estimation_tables(seeds)
    res["estimation"] = est
    plan_res = planning(grid)
    clear = clear_gap_plans(grid)
    c2c_from_level = {k: planner.plan(plan_res["land"], k, k, (-0.1, 0.0, 0.0)) for k in (K_FLIMSY, K_STIFF)}
    res["k0"], res["crossover_k"] = plan_res["k0"], plan_res["crossover_k"]
    res["critical_push_n"], res["contact"], res["kinetic_j"] = (plan_res[k] for k in ("critical_push_n", "contact",
                                                                                   "kinetic_j"))
    res["plans"] = {k: {"mode": p.mode, "barrier_J": p.barrier_j, "path_cost_J": p.path_cost_j}
                    for k, p in plan_res["plans"].items()}
    res["gap_modes"] = {"c2c": {str(k): p.mode for k, p in c2c_from_level.items()},
                        "clear": {str(k): p.mode for k, p in clear["plans"].items()}}
    res["energy"] = energy_runs(grid)
    res["robot"] = robot_validation(seeds)
    worse = []
    for key, errs in est["errors"].items():
        kind, level = key.split("/")
        paper = PAPER_TABLE4[int(level)] if kind == "Ts" else PAPER_TABLES[int(kind)][float(level)]
        for j, (ours, theirs) in enumerate(zip(np.median(errs, axis=0), paper)):
            if round(100 * ours) > round(100 * theirs):     # the paper prints whole percent
                known_hb = np.median(est["errors"][f"2/{level}"][:, j]) if kind != "Ts" and j < 2 else None
                why = "" if known_hb is None or known_hb <= theirs else \
                    f"; below even the 2-unknown median with h_b known, {_pct(known_hb)} %"
                worse.append(f"{'T_s ' + level + ' ms' if kind == 'Ts' else kind + ' unknowns ' + level}"
                             f" col {j + 1} ({_pct(ours)} vs {_pct(theirs)} %{why})")
    res["worse"] = "; ".join(worse)
    figs = {"noisy_forces": fig_noisy_forces(*est["fig3"], out / "fig3-noisy-forces.png"),
            "landscape": fig_landscape(plan_res, out / "fig4-landscape-path.png"),
            "gap_readings": fig_gap_readings({"land": plan_res["land"], "plans": c2c_from_level}, clear,
                                             out / "gap-readings.png"),
            "delay": fig_delay(res["energy"], out / "fig7-energy-vs-delay.png")}
    res["wall_s"] = time.perf_counter() - t0
    report = out / "force-sensing.md"
    report.write_text(markdown(res, quick, seeds, {k: p.name for k, p in figs.items()}))
    en = res["energy"]
    return {
        "report": str(report), "figures": [str(p) for p in figs.values()], "seeds": seeds, "quick": quick,
        "wall_s": res["wall_s"], "k0": res["k0"], "crossover_k": res["crossover_k"],
        "modes": {str(k): p["mode"] for k, p in res["plans"].items()},
        "gap_modes": res["gap_modes"],
        "no_control": {f"{r['fx_n']}N/{r['k1']}": r["outcome"] for r in res["no_control"]},
        "critical_push_n": {str(k): v for k, v in res["critical_push_n"].items()},
        "energy_mJ": {k: round(r["energy_J"] * 1e3, 2) for k, r in en.items()},
        "traversed": {k: r["traversed"] for k, r in en.items()},
        "estimation_median": {k: [round(float(v), 4) for v in np.median(e, axis=0)]
                              for k, e in est["errors"].items()},
        "estimation_bound_sd": {k: [round(float(v), 4) for v in sd] for k, sd in est["bounds"].items()},
        "robot": {name: {"k": float(np.median(r["noisy"][:, 0])), "tau0_nm": float(np.median(r["noisy"][:, 1])),
                         "k_noise_free": r["noise_free"]["k"], "tau0_noise_free": r["noise_free"]["tau0_nm"]}
                  for name, r in res["robot"].items()},
        "worse_than_paper": worse,
    }


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--quick", action="store_true", help="5 seeds and a 4 mm / 5 deg landscape grid (minutes)")
    p.add_argument("--out", default="out/force-sensing", help="output folder (force-sensing.md and PNGs)")
    p.add_argument("--seeds", type=int,
                   help="noise seeds 0..N-1 for the tables and the rig (default 20, 5 with --quick)")
    p.add_argument("--json", action="store_true", help="print a JSON summary as the last line")


def run(args: argparse.Namespace) -> int:
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out} exists and is not a folder")
    if args.seeds is not None and args.seeds < 1:
        raise UserError(f"--seeds must be at least 1, got {args.seeds}")
    try:
        summary = main(args.quick, out, args.seeds)
    except OSError as exc:
        raise UserError(f"cannot write into {out}: {exc.strerror}") from None
    emit(args, summary, f"report: {summary['report']} ({summary['wall_s']:.0f} s)")
    return 0
