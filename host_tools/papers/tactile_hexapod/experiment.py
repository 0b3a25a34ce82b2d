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
``hexhil.papers.tactile_hexapod.error_model``) from the run's own switch events. Runs without the method use
the same terrains and seeds as the low-density 1 m runs with it, so they pair up.
"""
from __future__ import annotations

import json
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Callable

from hexhil.papers.tactile_hexapod import error_model
from hexhil.executor import Executor
from hexhil.papers.tactile_hexapod.report import GAITS, markdown, plots, summary
from hexhil.hil.link.firmware_process import IN_PROCESS
from hexhil.hil.scenario import Scenario, parse
from hexhil.lockstep_run import Run
from hexhil.hil.scenario.world_section import OBSTACLE_BODY
from hexhil.protocol import hexapod

DENSITIES = ("low", "high")
HEIGHTS = ("small", "large")
HEIGHT_MAX_M = {"small": 0.05, "large": 0.08}   # H of Eq. 7: the class's maximum (Sec. 2.2)
PROBE_PERIODS = 4
CALIBRATION_TRIALS = 3       # Table 1: three trials per case (Sec. 3.3)
UNITS_SEED = 0               # the real model's servo spread: the same robot in every run
GOAL_MARGIN_M = 0.3          # terrain continues this far past the goal
NAVIGATOR_SLACK = 1.5        # a navigated run lasts up to this many times the planned periods
# lateral distance between the left and right foot lines: "a" of Eq. 12
ROBOT_WIDTH_M = 2 * hexapod.neutral_foot(1)[1]

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
    model: str = "real"   # world.model (hil/world/fidelity.py)
    obstacle_body: str = OBSTACLE_BODY   # world.obstacle_body with the real model
    navigator: str = ""   # "": no host node, the run ends after the planned periods; else one
                          # of hexhil.papers.tactile_hexapod.grnn.navigator.KINDS stops the walk
    model_path: str = ""  # the GRNN's model file with navigator "grnn"
    python: str = IN_PROCESS  # firmware runtime: in this process (micropython's digest, faster)

    @property
    def period_s(self) -> float:
        return hexapod.GAIT_PERIOD_S[self.gait]

    @property
    def duration_s(self) -> float:
        """A navigator may walk past the planned periods: the run leaves it room."""
        slack = NAVIGATOR_SLACK if self.navigator else 1.0
        return math.ceil(self.periods * slack) * self.period_s


def scenario_for(spec: RunSpec) -> Scenario:
    """The scenario a run walks, validated against the shared schema."""
    world: dict[str, Any] = {"kind": "hexapod", "terrain": "flat", "model": spec.model}
    if spec.model == "real":
        world["units_seed"] = UNITS_SEED    # one robot for every run, as in the paper
        world["obstacle_body"] = spec.obstacle_body
    gait: dict[str, Any] = {"name": spec.gait, "period_s": spec.period_s,
                            "distance_m": spec.distance_m}
    if spec.density:
        world.update(terrain="obstacles", density=spec.density, height_class=spec.height_class,
                     length_m=spec.distance_m + GOAL_MARGIN_M)
        gait["max_obstacle_height_m"] = HEIGHT_MAX_M[spec.height_class]
    name = f"tactile-hexapod-{spec.stage}"
    data = {"scenario": {"name": name, "seed": spec.seed, "duration_s": spec.duration_s},
            "gait": gait, "firmware": {"tactile": spec.tactile}, "world": world}
    return parse(data, f"<{name}>")


def simulate(scenario: Scenario, seed: int, duration_s: float, trace: str | None = None,
             navigate: Callable[[Run], Any] | None = None, python: str = IN_PROCESS):
    """Run the firmware (under ``python``) against the hexapod world (recorded to ``trace``
    if given: its metadata carries the scenario itself, whose path names no file); returns
    the world at the end. ``navigate(run)`` may add a host node first."""
    # the experiment's own folder: a re-run replaces its traces
    with Run(scenario, seed=seed, runtime=python, duration_s=duration_s, trace=trace,
             overwrite=True) as run:
        if navigate is not None:
            navigate(run)
        run.run()
    return run.world


def trace_name(spec: RunSpec) -> str:
    terrain = f"{spec.density}-{spec.height_class}" if spec.density else "flat"
    method = "tactile" if spec.tactile else "no-tactile"
    nav = f"-{spec.navigator}" if spec.navigator else ""
    return (f"{spec.stage}-{spec.gait}-{terrain}-{spec.distance_m:g}m-seed{spec.seed}-"
            f"{method}{nav}.mcap")


def run_one(spec: RunSpec, speed_m_s: float | None = None,
            trace_dir: str | None = None) -> dict[str, Any]:
    """One run: end-pose errors, switch counts and the Eq. 8-14 prediction."""
    t0 = time.perf_counter()
    trace = str(Path(trace_dir) / trace_name(spec)) if trace_dir else None
    nav: list[Any] = []
    navigate = None
    if spec.navigator:
        from hexhil.papers.tactile_hexapod.grnn import navigator

        def navigate(run: Run) -> None:
            args = (spec.gait, spec.period_s, hexapod.STEP_LENGTH_M, spec.distance_m)
            est = navigator.make_estimator(spec.navigator, spec.model_path, *args, speed_m_s)
            nav.append(navigator.attach(run, run.world, est, *args, spec.periods, speed_m_s))
    world = simulate(scenario_for(spec), spec.seed, spec.duration_s, trace, navigate, spec.python)
    pose = world.body_pose()
    out = asdict(spec)
    if nav:
        out["navigation"] = nav[0].summary()
    out.update(x_m=pose.x_m, dx_m=spec.distance_m - pose.x_m, dy_m=pose.y_m,
               dyaw_deg=math.degrees(pose.yaw_rad), presses=list(world.switches.presses),
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


def run_with_speed(args: tuple[Any, ...]) -> dict[str, Any]:
    """``run_one(*args)`` for an executor, which passes one argument."""
    return run_one(*args)


def plan(quick: bool, seeds: int, periods_for: dict[tuple[str, float], int],
         model: str = "real", trials: int = 1, obstacle_body: str = OBSTACLE_BODY,
         python: str = IN_PROCESS) -> list[RunSpec]:
    """Stages 2-4 of the protocol (the probe has run and fixed the periods). Table 1's
    trials differ by their seed (the real model's trial noise; identical when ideal)."""
    distances = (1.0,) if quick else (1.0, 2.0)
    specs = [RunSpec("calibration", g, d, True, t, periods=periods_for[g, d], model=model,
                     obstacle_body=obstacle_body, python=python)
             for g in GAITS for d in distances for t in range(trials)]
    for g in GAITS:
        for h in HEIGHTS:
            for s in range(seeds):
                specs.append(RunSpec("without", g, 1.0, False, s + 1, "low", h,
                                     periods_for[g, 1.0], model, obstacle_body, python=python))
    for g in GAITS:
        for dens in DENSITIES:
            for d in distances:
                for h in HEIGHTS:
                    for s in range(seeds):
                        specs.append(RunSpec("with", g, d, True, s + 1, dens, h,
                                             periods_for[g, d], model, obstacle_body,
                                             python=python))
    # longest runs first keeps the pool busy to the end
    return sorted(specs, key=lambda s: -s.duration_s)


def calibrate(executor: Executor, distances: tuple[float, ...], model: str = "real",
              obstacle_body: str = OBSTACLE_BODY, python: str = IN_PROCESS
              ) -> tuple[dict[str, float], dict[tuple[str, float], int]]:
    """Stage 1, the probe: each gait's flat-ground speed (m/s) and the gait periods that
    reach each distance at it (Sec. 3.3). Shared with ``hexhil grnn dataset``."""
    probes = [RunSpec("probe", g, 0.0, True, 0, model=model, obstacle_body=obstacle_body,
                      python=python) for g in GAITS]
    probe_out = executor.map(run_one, probes, "calibration probe")
    speed = {r["gait"]: r["x_m"] / r["sim_s"] for r in probe_out}
    periods_for = {(g, d): hexapod.periods_for_distance(d, speed[g], hexapod.GAIT_PERIOD_S[g])
                   for g in GAITS for d in distances}
    return speed, periods_for


def run_sweep(quick: bool, seeds: int, executor: Executor, trace_dir: str | None = None,
              model: str = "real", obstacle_body: str = OBSTACLE_BODY, python: str = IN_PROCESS
              ) -> dict[str, Any]:
    """Run the whole protocol; returns the probe speeds, periods and every run's result."""
    distances = (1.0,) if quick else (1.0, 2.0)
    speed, periods_for = calibrate(executor, distances, model, obstacle_body, python)
    specs = plan(quick, seeds, periods_for, model, 1 if quick else CALIBRATION_TRIALS,
                 obstacle_body, python)
    runs = executor.map(run_with_speed, [(s, speed[s.gait], trace_dir) for s in specs], "runs")
    return {"model": model, "obstacle_body": obstacle_body, "speed_m_s": speed, "periods": {f"{g} {d:g} m": n for (g, d), n in periods_for.items()},
            "runs": runs}


@dataclass(frozen=True)
class SweepOptions:
    """The sweep ``main`` runs: the whole protocol, or ``quick`` (1 m only, one trial)."""
    quick: bool = False
    seeds: int = 3                       # terrains per case (as the paper's three trials)
    traces: bool = False                 # one MCAP trace per run into OUT/traces
    model: str = "real"                  # world.model (hil/world/fidelity.py MODELS)
    obstacle_body: str = OBSTACLE_BODY   # with the real model (fidelity.OBSTACLE_BODIES)
    python: str = IN_PROCESS             # firmware runtime


def main(out: Path, opts: SweepOptions, executor: Executor) -> dict[str, Any]:
    """Run the sweep and write results.json, results.md and the PNG plots into ``out``
    (and one MCAP trace per run into ``out/traces`` with ``opts.traces``); returns the
    summary (files, runs, seconds and the headline numbers of ``tactile_report.summary``)."""
    out.mkdir(parents=True, exist_ok=True)
    trace_dir = None
    if opts.traces:
        (out / "traces").mkdir(exist_ok=True)
        trace_dir = str(out / "traces")
    t0 = time.perf_counter()
    result = run_sweep(opts.quick, opts.seeds, executor, trace_dir, opts.model,
                       opts.obstacle_body, opts.python)
    result["wall_s"] = time.perf_counter() - t0
    (out / "results.json").write_text(json.dumps(result, indent=1, sort_keys=True) + "\n")
    md = markdown(result, opts.quick)
    (out / "results.md").write_text(md)
    pngs = plots(result, out)
    return {"out": str(out), "table": str(out / "results.md"), "plots": [str(p) for p in pngs],
            "runs": len(result["runs"]), "wall_s": result["wall_s"], **summary(result)}
