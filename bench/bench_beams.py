"""Seed 000 benchmarks: fast vs paper estimator (same data), landscape + Dijkstra, dynamics."""
from __future__ import annotations

import time

import numpy as np

from bench import Row


def run() -> list[Row]:
    from hexhil.hil.world.beam_body import BeamParams
    from hexhil.hil.world.beams import BeamsWorld
    from hexhil.papers.beam_traversal import estimator, landscape, planner
    from hexhil.papers.beam_traversal.push import push_samples

    rows: list[Row] = []
    poses, forces = push_samples(0.25, 0.27, 0.0, 0.0, 0.2, 300, 1)     # Table 1 set-up, 20 % noise
    fast = [estimator.estimate(poses, forces, 4, "fast") for _ in range(5)]
    t_fast = float(np.median([e.elapsed_s for e in fast]))
    paper = estimator.estimate(poses, forces, 4, "paper")               # 100 restarts
    rel = lambda e: max(abs(e.k1 - 0.25) / 0.25, abs(e.k2 - 0.27) / 0.27)  # noqa: E731
    rows += [
        Row("beams: fast estimate (4 unknowns)", t_fast * 1e3, "ms", "<= 20 ms",
            f"max k error {rel(fast[0]):.1%}, Eq.7 error {fast[0].error_n:.3f} N"),
        Row("beams: paper estimate (NM x100)", paper.elapsed_s, "s", "",
            f"max k error {rel(paper):.1%}, Eq.7 error {paper.error_n:.3f} N"),
        Row("beams: fast vs paper speed-up", paper.elapsed_s / t_fast, "x", ">= 100x", "same data"),
    ]
    t0 = time.perf_counter()
    land = landscape.build(landscape.paper_grid())
    t_land = time.perf_counter() - t0
    p = planner.plan(land, 0.25, 0.25, (-0.1, 0.0, 0.0))
    t_all = time.perf_counter() - t0
    rows.append(Row("beams: landscape + Dijkstra (full grid)", t_all, "s", "<= 5 s",
                    f"{land.theta1_rad.size:,} states; landscape {t_land:.2f} s; mode {p.mode}"))
    w = BeamsWorld([BeamParams(0.25), BeamParams(0.25)])
    t0 = time.perf_counter()
    while w.t_us < 2_000_000:
        w.command(0.1, 0.0, 0.0)
        w.step()
    rows.append(Row("beams: dynamics at dt 0.2 ms (in contact)", w.t_us * 1e-6 / (time.perf_counter() - t0),
                    "x real time", ">= 5x", "stiff beams, 2 s"))
    return rows
