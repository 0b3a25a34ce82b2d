"""``hexhil experiment force-sensing``: seed 000's results reproduced (Xuan, Wang & Li,
``/work/shared/seeds/000_*.txt``), ours beside the paper's.

Sections, in the paper's order (Sec. III-IV):

* no control (Sec. III-A, Fig. 5): F_x = 0.1 / 1 N into flimsy (k = 0.01) and stiff (0.25) beams;
* estimation (Sec. III-B, Tables 1-4): relative errors over noise seeds, fast estimator;
* planning (Sec. II-G/H, III-C): k0, the landscape's own crossover, planned modes;
* energy (Sec. III-D, Eq. 11): interaction vs the obstacle-avoidance baseline;
* sensory delay (Sec. III-E, Fig. 7): energy at 100 / 300 / 600 ms;
* robot validation (Sec. IV, Eq. 12): k and tau_0 from a prescribed-speed push.

Everything reuses hil/world/ and host_tools/papers/beam_traversal/; this package only sweeps
(``sections``), draws (``figures``) and reports (``report``).
"""
from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from hexhil.papers.beam_traversal.force_sensing import figures, report
from hexhil.papers.beam_traversal.force_sensing.sections import (K_FLIMSY, K_STIFF, clear_gap_plans, energy_runs,
                                                           estimation_tables, no_control, planning,
                                                           robot_validation)
from hexhil.papers.beam_traversal import landscape, planner


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
    worse = report.worse_than_paper(est["errors"])
    res["worse"] = "; ".join(worse)
    figs = {"noisy_forces": figures.fig_noisy_forces(*est["fig3"], out / "fig3-noisy-forces.png"),
            "landscape": figures.fig_landscape(plan_res, out / "fig4-landscape-path.png"),
            "gap_readings": figures.fig_gap_readings({"land": plan_res["land"], "plans": c2c_from_level}, clear,
                                                     out / "gap-readings.png"),
            "delay": figures.fig_delay(res["energy"], out / "fig7-energy-vs-delay.png")}
    res["wall_s"] = time.perf_counter() - t0
    report_md = out / "force-sensing.md"
    report_md.write_text(report.markdown(res, quick, seeds, {k: p.name for k, p in figs.items()}))
    en = res["energy"]
    return {
        "report": str(report_md), "figures": [str(p) for p in figs.values()], "seeds": seeds, "quick": quick,
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
