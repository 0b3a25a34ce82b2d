"""The force-sensing experiment's report, ``force-sensing.md``: our tables beside the paper's."""
from __future__ import annotations

from typing import Any

import numpy as np

from hexhil.papers.beam_traversal.force_sensing.sections import (DELAY_SERIES, DELAYS_MS, FX_GENTLE_N, FX_SENSING_N,
                                                           K_FLIMSY, K_STIFF, NOISES, PAPER_ENERGY_MJ, PAPER_K0,
                                                           PAPER_ROBOT_ESTIMATE, PAPER_TABLE4, PAPER_TABLES,
                                                           ROBOT_K, ROBOT_MB_KG, ROBOT_NOISE, ROBOT_TAU0_NM,
                                                           SENSING_MS)


def _pct(x: float) -> str:
    return f"{100 * x:.1f}"


def _med_iqr(col: np.ndarray) -> str:
    q1, med, q3 = np.percentile(col, [25, 50, 75])
    return f"{_pct(med)} [{_pct(q1)}-{_pct(q3)}]"


def worse_than_paper(errors: dict[str, np.ndarray]) -> list[str]:
    """The table cells whose median error is above the paper's single trial, with the
    2-unknown median beside it where knowing h_b would not have helped either."""
    worse = []
    for key, errs in errors.items():
        kind, level = key.split("/")
        paper = PAPER_TABLE4[int(level)] if kind == "Ts" else PAPER_TABLES[int(kind)][float(level)]
        for j, (ours, theirs) in enumerate(zip(np.median(errs, axis=0), paper)):
            if round(100 * ours) > round(100 * theirs):     # the paper prints whole percent
                known_hb = np.median(errors[f"2/{level}"][:, j]) if kind != "Ts" and j < 2 else None
                why = "" if known_hb is None or known_hb <= theirs else \
                    f"; below even the 2-unknown median with h_b known, {_pct(known_hb)} %"
                worse.append(f"{'T_s ' + level + ' ms' if kind == 'Ts' else kind + ' unknowns ' + level}"
                             f" col {j + 1} ({_pct(ours)} vs {_pct(theirs)} %{why})")
    return worse


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
