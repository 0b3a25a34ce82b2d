"""``hexhil grnn dataset``: the GRNN's training data (seed 003 Sec. 2.6) from our own runs.

Without trace arguments: the tactile-hexapod experiment's protocol (its calibration probe,
``run_one`` with traces, real world model with fixed obstacles by default), one with-method
run per terrain seed S..S+N-1,
gait x density x height class cycling through the 8 combinations by seed. Each trace is
turned into one row per step by ``features.StepSampler``, fed from the trace in time order:
``tactile`` frames from /can/raw, ground truth from /body and /joints. With MCAP arguments,
those traces are read instead and their run facts come from the trace's metadata.
"""
from __future__ import annotations

import math
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hexhil.hil.scenario.world_section import OBSTACLE_BODY
from hexhil.hil.world.hexapod_world import yaw_rad
from hexhil.papers.tactile_hexapod.grnn import data as data_mod
from hexhil.hil.scenario import WorldKind, check_seed
from hexhil.papers.tactile_hexapod.grnn.features import StepRow, StepSampler
from hexhil.progress import Progress
from hexhil.trace.run_metadata import scenario_of_trace
from hexhil.trace.reader import Trace
from hexhil.trace.topics import T_BODY, T_CAN_RAW, T_JOINTS
from hexhil.protocol import can_frames, hexapod
from hexhil.protocol.errors import BadFile, BadValue

COMBINATIONS = [(g, dens, h) for g in ("tripod", "wave") for dens in ("low", "high")
                for h in ("small", "large")]   # the with-method cases of Fig. 17-20


def rows_from_trace(path: str | Path) -> tuple[list[StepRow], dict[str, Any]]:
    """One trace's rows and its run facts (gait, terrain, d, N, dx at the last pose)."""
    with Trace(path) as tr:
        sc, seed = scenario_of_trace(tr.metadata(), str(tr.path))
        gait, kind, world = sc.gait, sc.world.kind, sc.world
        name, period_s, distance_m = gait.name, gait.period_s, gait.distance_m or 0.0
        if kind is not WorldKind.HEXAPOD or not distance_m > 0:
            raise BadValue(f"{tr.path}: not a hexapod walk to a goal (world.kind "
                           f"{kind.value if kind else None!r}, gait.distance_m {distance_m})")
        sampler = StepSampler(name, period_s, gait.step_length_m or hexapod.STEP_LENGTH_M)
        topics = [t for t in (T_CAN_RAW, T_BODY, T_JOINTS) if t in tr.topics()]
        if len(topics) < 3:
            raise BadValue(f"{tr.path}: needs {T_CAN_RAW}, {T_BODY} and {T_JOINTS} "
                           f"(has {', '.join(tr.topics())})")
        rows: list[StepRow] = []
        body: tuple[int, float, float, float] | None = None
        joints: tuple[int, list[float]] | None = None
        first = last = None
        for m, v in tr.decoded(topics):
            t_us = m.log_time_ns // 1000
            if m.topic == T_CAN_RAW:
                if v["arbitration_id"] == can_frames.ID_TACTILE:
                    _, s = can_frames.decode(v["arbitration_id"], bytes.fromhex(v["data"]))
                    sampler.tactile(t_us, s["switches"], s["overcoming"], s["step_counter"])
                continue
            if m.topic == T_BODY:
                body = (t_us, v["translation"]["x"], v["translation"]["y"], yaw_rad(*(v["rotation"][k] for k in "wxyz")))
                first = first or body
                last = body
            else:
                joints = (t_us, [j["position"] for j in v["joints"]])
            if body is not None and joints is not None and body[0] == joints[0]:
                row = sampler.truth(t_us, body[1], body[2], body[3], joints[1])
                if row is not None:
                    rows.append(row)
        end_s = tr.summary.statistics.message_end_time / 1e9
    if first is None or last is None:
        raise BadValue(f"{path}: no ground-truth samples on {T_BODY}")
    x_end = last[1] - first[1]
    generated = world.terrain == "obstacles" and world.obstacles is None
    facts = {"terrain_seed": seed if world.terrain_seed is None else world.terrain_seed,
             "gait": name, "density": world.density if generated else "",
             "height_class": world.height_class if generated else "",
             "distance_m": distance_m, "periods": max(1, round(end_s / period_s)),
             "dx_m": distance_m - x_end, "x_end_m": x_end, "model_dx_m": math.nan,
             "source": str(path)}
    return rows, facts


def build_one(args: tuple[Any, float, str]) -> tuple[dict[str, Any], list[StepRow]]:
    """One with-method run with its trace, then its rows (in a worker process)."""
    from hexhil.papers.tactile_hexapod import experiment as th

    spec, speed_m_s, trace_dir = args
    t0 = time.perf_counter()
    r = th.run_one(spec, speed_m_s, trace_dir)
    rows, facts = rows_from_trace(r["trace"])
    facts.update(dx_m=r["dx_m"], x_end_m=r["x_m"], model_dx_m=r["model_dx_m"],
                 periods=spec.periods, build_s=time.perf_counter() - t0)
    return facts, rows


@dataclass(frozen=True)
class DatasetOptions:
    """What ``build`` makes: from ``traces`` when given, else a sweep of ``terrains``
    with-method runs from terrain seed ``seed`` to the goal ``distance_m`` ahead."""
    traces: tuple[str, ...] = ()
    terrains: int = 32
    seed: int = 1
    distance_m: float = 1.0      # d, as the paper's runs
    obstacles: str = OBSTACLE_BODY   # world.obstacle_body (hil/world/fidelity.py)
    workers: int = 1


@dataclass(frozen=True)
class DatasetResult:
    """The files written and what building them took."""
    dataset: str                 # dataset.npz
    sidecar: str                 # dataset.json
    runs: int
    rows: int                    # steps over all runs
    wall_s: float
    build_s_per_run: list[float]


def simulate_runs(out_dir: Path, opts: DatasetOptions, progress: Progress | None = None
                  ) -> tuple[list[dict[str, Any]], list[list[StepRow]], dict]:
    """The experiment's probe, then one traced with-method run per terrain seed."""
    from hexhil.papers.tactile_hexapod import experiment as th
    from hexhil.executor import Executor

    ex = Executor(opts.workers, progress=progress)
    distance_m, obstacles = opts.distance_m, opts.obstacles
    speed, periods_for = th.calibrate(ex, (distance_m,), "real", obstacles)
    trace_dir = out_dir / "traces"
    trace_dir.mkdir(parents=True, exist_ok=True)
    jobs = []
    for s in range(opts.seed, opts.seed + opts.terrains):
        g, dens, h = COMBINATIONS[s % len(COMBINATIONS)]
        spec = th.RunSpec("with", g, distance_m, True, s, dens, h, periods_for[g, distance_m],
                          "real", obstacles)
        jobs.append((spec, speed[g], str(trace_dir)))
    out = ex.map(build_one, jobs, "runs")
    return ([f for f, _ in out], [r for _, r in out],
            {"probe_speed_m_s": speed, "world": {"model": "real", "obstacle_body": obstacles},
             "stage": "with",
             "periods": {f"{g} {d:g} m": n for (g, d), n in periods_for.items()}})


def code_version() -> str:
    """``git describe`` of the checkout when there is one, else the package version."""
    try:
        out = subprocess.run(["git", "describe", "--always", "--dirty"], capture_output=True,
                             text=True, timeout=10, cwd=Path(__file__).resolve().parent)
        if out.returncode == 0 and out.stdout.strip():
            return out.stdout.strip()
    except OSError:
        pass
    from hexhil.trace.writer import software_version

    return software_version()


def build(out_dir: Path, opts: DatasetOptions, progress: Progress | None = None
          ) -> DatasetResult:
    """Make the dataset in ``out_dir``; a sweep's runs are reported to ``progress``."""
    if out_dir.exists() and not out_dir.is_dir():
        raise BadFile(f"out_dir {out_dir} exists and is not a folder", params=("out_dir",))
    t0 = time.perf_counter()
    if opts.traces:
        runs, rows = [], []
        for p in opts.traces:
            t1 = time.perf_counter()
            r, f = rows_from_trace(p)
            f["build_s"] = time.perf_counter() - t1
            runs.append(f)
            rows.append(r)
        extra: dict[str, Any] = {"note": "built from traces: dx_m from the last /body sample; "
                                         "model_dx_m (Eq. 8-14) omitted (NaN), it needs the "
                                         "probe-calibrated speed the trace does not hold"}
    else:
        if opts.terrains < 1:
            raise BadValue(f"terrains must be at least 1, got {opts.terrains}",
                           params=("terrains",))
        check_seed(opts.seed, "seed", params=("seed",))
        check_seed(opts.seed + opts.terrains - 1, "seed + terrains - 1 (the last terrain seed)",
                   params=("seed", "terrains"))
        if not opts.distance_m > 0:
            raise BadValue(f"distance_m must be positive, got {opts.distance_m}",
                           params=("distance_m",))
        runs, rows, extra = simulate_runs(out_dir, opts, progress)
    meta = {**data_mod.feature_meta(), "code_version": code_version(), "terrain_seeds": [int(r["terrain_seed"]) for r in runs],
            "scenarios": sorted({f"{r['gait']}-{r['density']}-{r['height_class']}" for r in runs}),
            **extra}
    path = data_mod.write(out_dir, runs, rows, meta)
    return DatasetResult(str(path), str(out_dir / "dataset.json"), len(runs),
                         sum(len(r) for r in rows), time.perf_counter() - t0,
                         [r["build_s"] for r in runs])
