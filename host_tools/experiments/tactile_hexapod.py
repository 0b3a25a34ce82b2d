"""Seed 003's experiments in simulation: the firmware (tactile rule on or off) walking the
MuJoCo hexapod over generated obstacle terrain (Sections 3.3 and 4).

Protocol, as in the paper:

1. calibration probe: each gait walks flat ground; its measured speed gives the number of
   gait periods needed to reach a goal ``d`` ahead ("steps needed to reach the goal",
   Sec. 3.3); every later run of that gait and distance walks exactly that many periods;
2. calibration (Table 1): flat ground, d = 1 m and 2 m, both gaits;
3. without the method (Fig. 16): low density, d = 1 m, both gaits and height classes;
4. with the method (Fig. 17-20): 2 gaits x 2 densities x 2 distances x 2 height classes.

Each run records dx (goal x minus end x), dy (end y) and the heading change at the goal,
as in Sections 2.5 and 3.3, and evaluates the analytic error model (Eq. 8-14,
``host_tools.error_model``) from the run's own switch events. Runs without the method use
the same terrains and seeds as the low-density 1 m runs with it, so they pair up.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from host_tools import error_model
from host_tools.cli import emit_json
from protocol.errors import UserError
from host_tools.experiments.executor import Executor
from hil.scenario import check
from protocol import hexapod

GAITS = ("wave", "tripod")
DENSITIES = ("low", "high")
HEIGHTS = ("small", "large")
HEIGHT_MAX_M = {"small": 0.05, "large": 0.08}   # H of Eq. 7: the class's maximum (Sec. 2.2)
PROBE_PERIODS = 4
GOAL_MARGIN_M = 0.3          # terrain continues this far past the goal
# lateral distance between the left and right foot lines: "a" of Eq. 12
ROBOT_WIDTH_M = 2 * hexapod.neutral_foot(1)[1]

# The paper's numbers (seed 003), shown beside ours.
PAPER_TABLE1_CM = {("wave", 1.0): (2, 1), ("wave", 2.0): (2, 5), ("tripod", 1.0): (1, 2),
                   ("tripod", 2.0): (3, 5)}                           # Table 1 averages
PAPER_FIG16 = {("wave", "small"): (25.2, 11.4, 17.4), ("wave", "large"): (22.4, 2.6, 6.8),
               ("tripod", "small"): (25.2, 12.6, 22.8), ("tripod", "large"): (22.0, 0.8, 12.0)}
PAPER_REL_ERROR = {"without": 0.24, "with": 0.12}                     # Sec. 4
PAPER_WAVE_WINS = (6, 8)                                              # Fig. 20


@dataclass(frozen=True)
class RunSpec:
    stage: str            # probe, calibration, without, with
    gait: str
    distance_m: float
    tactile: bool
    seed: int
    density: str = ""     # "" = flat ground
    height_class: str = ""
    periods: int = PROBE_PERIODS

    @property
    def period_s(self) -> float:
        return hexapod.GAIT_PERIOD_S[self.gait]

    @property
    def duration_s(self) -> float:
        return self.periods * self.period_s


def scenario_for(spec: RunSpec) -> dict[str, Any]:
    """The scenario a run walks, validated against the shared schema."""
    world: dict[str, Any] = {"kind": "hexapod", "terrain": "flat"}
    gait: dict[str, Any] = {"name": spec.gait, "period_s": spec.period_s,
                            "distance_m": spec.distance_m}
    if spec.density:
        world.update(terrain="obstacles", density=spec.density, height_class=spec.height_class,
                     length_m=spec.distance_m + GOAL_MARGIN_M)
        gait["max_obstacle_height_m"] = HEIGHT_MAX_M[spec.height_class]
    data = {"scenario": {"name": f"tactile-hexapod-{spec.stage}", "seed": spec.seed,
                         "duration_s": spec.duration_s},
            "gait": gait, "firmware": {"tactile": spec.tactile}, "world": world}
    return check(data, f"<{data['scenario']['name']}>")


def simulate(scenario: dict[str, Any], seed: int, duration_s: float, trace: str | None = None):
    """Run the firmware against the hexapod world (recorded to ``trace`` if given);
    returns the world at the end."""
    from hil.sim import Simulator
    from hil.world.hexapod import HexapodWorld
    from host_tools.trace.recorder import open_recorder

    world = HexapodWorld(scenario, seed)
    recorder = open_recorder(trace, {"scenario": scenario["_path"], "seed": seed,
                                     "firmware_runtime": "micropython"})
    try:
        Simulator(scenario, seed, world=world, recorder=recorder).run(duration_s)
    finally:
        if recorder is not None:
            recorder.close()
    return world


def trace_name(spec: RunSpec) -> str:
    terrain = f"{spec.density}-{spec.height_class}" if spec.density else "flat"
    method = "tactile" if spec.tactile else "no-tactile"
    return f"{spec.stage}-{spec.gait}-{terrain}-{spec.distance_m:g}m-seed{spec.seed}-{method}.mcap"


def run_one(spec: RunSpec, speed_m_s: float | None = None,
            trace_dir: str | None = None) -> dict[str, Any]:
    """One run: end-pose errors, switch counts and the Eq. 8-14 prediction."""
    t0 = time.perf_counter()
    trace = str(Path(trace_dir) / trace_name(spec)) if trace_dir else None
    world = simulate(scenario_for(spec), spec.seed, spec.duration_s, trace)
    pose = world.body_pose()
    out = asdict(spec)
    out.update(x_m=pose.x_m, dx_m=spec.distance_m - pose.x_m, dy_m=pose.y_m,
               dyaw_deg=math.degrees(pose.yaw_rad), presses=[int(p) for p in world.switches.presses],
               obstacles=len(world.obstacles), wall_s=time.perf_counter() - t0,
               sim_s=world.t_us * 1e-6)
    out["trace"] = trace
    out["error_m"] = math.hypot(out["dx_m"], out["dy_m"])
    out["rel_error"] = out["error_m"] / spec.distance_m if spec.distance_m else float("nan")
    if speed_m_s is not None:
        p = error_model.predict([(e.t_us, e.leg, e.closed) for e in world.events], world.trajectory,
                                speed_m_s, spec.distance_m, ROBOT_WIDTH_M)
        out.update(model_dx_m=p.dx_m, model_dy_m=p.dy_m, model_dalpha_deg=math.degrees(p.dalpha_rad),
                   model_hits=p.hits)
    return out


def _run_with_speed(args: tuple[RunSpec, float]) -> dict[str, Any]:
    return run_one(*args)


def plan(quick: bool, seeds: int, periods_for: dict[tuple[str, float], int]) -> list[RunSpec]:
    """Stages 2-4 of the protocol (the probe has run and fixed the periods)."""
    distances = (1.0,) if quick else (1.0, 2.0)
    specs = [RunSpec("calibration", g, d, True, 0, periods=periods_for[g, d])
             for g in GAITS for d in distances]
    for g in GAITS:
        for h in HEIGHTS:
            for s in range(seeds):
                specs.append(RunSpec("without", g, 1.0, False, s + 1, "low", h, periods_for[g, 1.0]))
    for g in GAITS:
        for dens in DENSITIES:
            for d in distances:
                for h in HEIGHTS:
                    for s in range(seeds):
                        specs.append(RunSpec("with", g, d, True, s + 1, dens, h, periods_for[g, d]))
    # longest runs first keeps the pool busy to the end
    return sorted(specs, key=lambda s: -s.duration_s)


def run_sweep(quick: bool, seeds: int, executor: Executor,
              trace_dir: str | None = None) -> dict[str, Any]:
    """Run the whole protocol; returns the probe speeds, periods and every run's result."""
    probes = [RunSpec("probe", g, 0.0, True, 0) for g in GAITS]
    probe_out = executor.map(run_one, probes, "calibration probe")
    speed = {r["gait"]: r["x_m"] / r["sim_s"] for r in probe_out}
    distances = (1.0,) if quick else (1.0, 2.0)
    periods_for = {(g, d): max(1, round(d / (speed[g] * hexapod.GAIT_PERIOD_S[g])))
                   for g in GAITS for d in distances}
    specs = plan(quick, seeds, periods_for)
    runs = executor.map(_run_with_speed, [(s, speed[s.gait], trace_dir) for s in specs], "runs")
    return {"speed_m_s": speed, "periods": {f"{g} {d:g} m": n for (g, d), n in periods_for.items()},
            "runs": runs}


# --- reporting ------------------------------------------------------------------------
def _mean(xs: list[float]) -> float:
    return sum(xs) / len(xs) if xs else float("nan")


def _cases(runs: list[dict[str, Any]], stage: str) -> dict[tuple, list[dict[str, Any]]]:
    out: dict[tuple, list[dict[str, Any]]] = {}
    for r in runs:
        if r["stage"] == stage:
            out.setdefault((r["gait"], r["density"], r["distance_m"], r["height_class"]), []).append(r)
    return dict(sorted(out.items()))


def summary(result: dict[str, Any]) -> dict[str, Any]:
    """Headline numbers: mean relative errors without/with the method, wave-vs-tripod wins,
    paired comparison on identical terrain."""
    runs = result["runs"]
    rel = {st: _mean([r["rel_error"] for r in runs if r["stage"] == st]) for st in ("without", "with")}
    with_cases = _cases(runs, "with")
    wins = total = 0
    for (g, dens, d, h), rs in with_cases.items():
        if g != "wave":
            continue
        other = with_cases.get(("tripod", dens, d, h))
        if other:
            total += 1
            wins += _mean([r["error_m"] for r in rs]) < _mean([r["error_m"] for r in other])
    pairs = {(r["gait"], r["height_class"], r["seed"]): r for r in runs
             if r["stage"] == "with" and r["density"] == "low" and r["distance_m"] == 1.0}
    nearer = [pairs[k]["error_m"] < r["error_m"] for r in runs if r["stage"] == "without"
              for k in [(r["gait"], r["height_class"], r["seed"])] if k in pairs]
    return {"rel_error_without": rel["without"], "rel_error_with": rel["with"],
            "improvement": rel["without"] / rel["with"] if rel["with"] else float("nan"),
            "wave_wins": [wins, total], "paired_nearer_with_method": [sum(nearer), len(nearer)]}


def markdown(result: dict[str, Any], quick: bool) -> str:
    runs = result["runs"]
    s = summary(result)
    lines = ["# Seed 003 in simulation: tactile obstacle overcoming", "",
             f"Sweep: {'quick' if quick else 'full'}; {len(runs)} runs after the calibration probe. "
             "Errors in cm, heading change in degrees; dx = goal x - end x, dy = end y.",
             f"Measured flat-ground speed: " + ", ".join(f"{g} {v:.4f} m/s" for g, v in result["speed_m_s"].items())
             + " (paper: wave 0.013, tripod 0.036 m/s); gait periods walked: "
             + ", ".join(f"{k}: {v}" for k, v in result["periods"].items()) + ".", "",
             "## Headline", "",
             "| quantity | ours | paper |", "|---|---|---|",
             f"| mean relative error without the method | {100 * s['rel_error_without']:.1f} % | ~24 % |",
             f"| mean relative error with the method | {100 * s['rel_error_with']:.1f} % | ~12 % |",
             f"| improvement | {s['improvement']:.2f}x | ~2x |",
             f"| wave better than tripod | {s['wave_wins'][0]} of {s['wave_wins'][1]} cases | 6 of 8 |",
             f"| same terrain and seed: nearer the goal with the method | {s['paired_nearer_with_method'][0]} "
             f"of {s['paired_nearer_with_method'][1]} | (robot does not reach the goal without) |", "",
             "## Calibration on flat ground (Table 1)", "",
             "| gait | d (m) | ours (dx, dy) | paper average (dx, dy) |", "|---|---|---|---|"]
    for (g, _, d, _), rs in _cases(runs, "calibration").items():
        r = rs[0]
        paper = PAPER_TABLE1_CM.get((g, d), ("", ""))
        lines.append(f"| {g} | {d:g} | ({100 * r['dx_m']:.1f}, {100 * r['dy_m']:.1f}) | ({paper[0]}, {paper[1]}) |")
    lines += ["", "## Without the method: low density, 1 m (Fig. 16)", "",
              "| gait | height | runs | ours mean abs (dx, dy) cm, dyaw deg | Eq. 8-14 (dx, dy) cm, dalpha deg | paper |",
              "|---|---|---|---|---|---|"]
    for (g, _, _, h), rs in _cases(runs, "without").items():
        paper = PAPER_FIG16[g, h]
        lines.append(f"| {g} | {h} | {len(rs)} | {_triple(rs, '')} | {_triple(rs, 'model_')} | "
                     f"({paper[0]}, {paper[1]}) {paper[2]} |")
    lines += ["", "## With the method (Fig. 17-20)", "",
              "| gait | density | d (m) | height | runs | mean error (cm) | relative | mean abs (dx, dy) cm, dyaw deg | Eq. 8-14 (dx, dy) cm, dalpha deg | switch presses |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for (g, dens, d, h), rs in _cases(runs, "with").items():
        err = _mean([r["error_m"] for r in rs])
        presses = _mean([sum(r["presses"]) for r in rs])
        lines.append(f"| {g} | {dens} | {d:g} | {h} | {len(rs)} | {100 * err:.1f} | {100 * err / d:.1f} % | "
                     f"{_triple(rs, '')} | {_triple(rs, 'model_')} | {presses:.0f} |")
    lines += ["", "Paper, Fig. 20: errors 4.16-16.5 cm at 1 m and 15.4-41.5 cm at 2 m with the method.", ""]
    return "\n".join(lines)


def _triple(rs: list[dict[str, Any]], prefix: str) -> str:
    if prefix and f"{prefix}dx_m" not in rs[0]:
        return "-"
    yaw = "model_dalpha_deg" if prefix else "dyaw_deg"
    return (f"({100 * _mean([abs(r[prefix + 'dx_m']) for r in rs]):.1f}, "
            f"{100 * _mean([abs(r[prefix + 'dy_m']) for r in rs]):.1f}) {_mean([abs(r[yaw]) for r in rs]):.1f}")


def plots(result: dict[str, Any], out: Path) -> list[Path]:
    """End positions (Fig. 16-18 style: arrows show the heading at the goal) and Fig. 20."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    runs = result["runs"]
    paths = []

    def ends(ax, rs, title):
        for r in rs:
            colour = "tab:blue" if r["height_class"] == "small" else "tab:red"
            x, y = r["distance_m"] - r["dx_m"], r["dy_m"]
            ax.quiver(x, y, math.cos(math.radians(r["dyaw_deg"])), math.sin(math.radians(r["dyaw_deg"])),
                      color=colour, angles="xy", scale=12, width=0.006)
            ax.plot(x, y, "o", color=colour, ms=3)
        if rs:
            ax.plot(rs[0]["distance_m"], 0, "k*", ms=12, label="goal")
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("x, m")
        ax.set_ylabel("y, m")
        ax.axis("equal")
        ax.grid(alpha=0.3)

    fig, axes = plt.subplots(1, 2, figsize=(9, 4))
    for ax, g in zip(axes, GAITS):
        ends(ax, [r for r in runs if r["stage"] == "without" and r["gait"] == g],
             f"{g}, without the method, low density, 1 m\n(blue small, red large obstacles)")
    fig.tight_layout()
    paths.append(out / "fig16_without_method.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)

    for fig_no, g in (("fig17", "wave"), ("fig18", "tripod")):
        cases = sorted({(r["density"], r["distance_m"]) for r in runs if r["stage"] == "with" and r["gait"] == g})
        fig, axes = plt.subplots(1, max(1, len(cases)), figsize=(4.5 * max(1, len(cases)), 4), squeeze=False)
        for ax, (dens, d) in zip(axes[0], cases):
            ends(ax, [r for r in runs if r["stage"] == "with" and r["gait"] == g and r["density"] == dens
                      and r["distance_m"] == d], f"{g} with the method: {dens} density, {d:g} m")
        fig.tight_layout()
        paths.append(out / f"{fig_no}_{g}_with_method.png")
        fig.savefig(paths[-1], dpi=110)
        plt.close(fig)

    cases = _cases(runs, "with")
    groups = sorted({(h, d, dens) for (_, dens, d, h) in cases})
    fig, ax = plt.subplots(figsize=(10, 4))
    for k, g in enumerate(GAITS):
        vals = [100 * _mean([r["error_m"] for r in cases.get((g, dens, d, h), [])]) for h, d, dens in groups]
        ax.bar([i + 0.4 * k - 0.2 for i in range(len(groups))], vals, width=0.4, label=g)
    ax.set_xticks(range(len(groups)))
    ax.set_xticklabels([f"{h}\n{d:g} m\n{dens}" for h, d, dens in groups], fontsize=8)
    ax.set_ylabel("distance error, cm")
    ax.set_title("Error at the goal with the method (Fig. 20 layout; shorter is better)")
    ax.legend()
    fig.tight_layout()
    paths.append(out / "fig20_gait_comparison.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)
    return paths


def main(quick: bool, out: Path, seeds: int, executor: Executor,
         traces: bool = False) -> dict[str, Any]:
    """Run the sweep and write results.json, results.md and the PNG plots into ``out``
    (and one MCAP trace per run into ``out/traces`` with ``traces``)."""
    out.mkdir(parents=True, exist_ok=True)
    trace_dir = None
    if traces:
        (out / "traces").mkdir(exist_ok=True)
        trace_dir = str(out / "traces")
    t0 = time.perf_counter()
    result = run_sweep(quick, seeds, executor, trace_dir)
    result["wall_s"] = time.perf_counter() - t0
    (out / "results.json").write_text(json.dumps(result, indent=1, sort_keys=True) + "\n")
    md = markdown(result, quick)
    (out / "results.md").write_text(md)
    pngs = plots(result, out)
    return {"out": str(out), "table": str(out / "results.md"), "plots": [str(p) for p in pngs],
            "runs": len(result["runs"]), "wall_s": result["wall_s"], **summary(result)}


# --- command line (``hexhil experiment tactile-hexapod``) -------------------------------
def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--quick", action="store_true",
                   help="reduced sweep: 1 m only, one seed per case (a few minutes on 2 cores)")
    p.add_argument("--out", default="out/tactile-hexapod", help="output folder (table, plots, JSON)")
    p.add_argument("--workers", type=int, default=max(1, os.cpu_count() or 1),
                   help="local worker processes (default: one per core)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on a Dask distributed cluster, e.g. tcp://127.0.0.1:8786")
    p.add_argument("--seeds", type=int, default=None,
                   help="terrains per case (default 1 with --quick, 3 otherwise)")
    p.add_argument("--traces", action="store_true",
                   help="record every run to an MCAP trace in OUT/traces")
    p.add_argument("--json", action="store_true", help="print a JSON summary as the last line")


def run(args: argparse.Namespace) -> int:
    seeds = args.seeds if args.seeds is not None else (1 if args.quick else 3)
    if seeds < 1:
        raise UserError(f"--seeds must be at least 1, got {seeds}")
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out} exists and is not a folder")
    res = main(args.quick, out, seeds, Executor(args.workers, args.scheduler), args.traces)
    print(Path(res["table"]).read_text())
    print(f"wrote {res['table']} and {len(res['plots'])} plots in {res['out']} "
          f"({res['runs']} runs, {res['wall_s']:.0f} s)")
    if args.json:
        emit_json(res)
    return 0
