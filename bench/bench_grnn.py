"""The GRNN predictor: training time per epoch, inference time per step (the
navigator must keep up with the step rate), and the dataset's build time per run.

As users run it: torch single-threaded as ``hexhil grnn train`` sets it, nothing pinned.
"""
from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

from bench import Row

TRAIN_WALKS = 24        # the acceptance's training set size, 15-30 steps a walk
TRAIN_EPOCHS = 5
REPEATS = 3
INFER_STEPS = 2000
# the probe's periods for d = 1 m on this world (hexhil grnn dataset prints them)
BUILD_RUNS = (("tripod", 11, 1), ("wave", 18, 2))


def _training_and_inference(tmp: Path) -> list[Row]:
    from hexhil.papers.tactile_hexapod.grnn import data, model, train

    runs, rows = data.synthetic(TRAIN_WALKS, 0, 1)
    path = data.write(tmp / "syn", runs, rows, data.feature_meta())
    ds = data.read(path)
    per_epoch = [train.fit(ds, TRAIN_EPOCHS, seed=r)[3] for r in range(REPEATS)]
    train.main(str(path), str(tmp / "m.pt"), epochs=1)
    pred = model.load(tmp / "m.pt")
    w = ds.sequences[0]
    sensing = [s.tolist() for s in w.sensing]
    pred.reset()
    times = []
    for i in range(INFER_STEPS):
        if i % len(sensing) == 0:
            pred.reset()
        t0 = time.perf_counter()
        pred.step(sensing[i % len(sensing)])
        times.append(time.perf_counter() - t0)
    steps = sum(len(r) for r in rows)
    return [
        Row("grnn: training time per epoch", statistics.median(per_epoch), "s", "",
            f"synthetic {TRAIN_WALKS} walks, {steps} steps, batch {train.BATCH}, 1 thread, "
            f"median of {REPEATS} x {TRAIN_EPOCHS} epochs"),
        Row("grnn: inference per step (Predictor.step)", 1e3 * statistics.median(times), "ms",
            "<= 1 ms", f"median of {INFER_STEPS}; p99 "
            f"{1e3 * sorted(times)[int(0.99 * len(times))]:.3f} ms"),
    ]


def _dataset_build(tmp: Path) -> Row:
    from hexhil.papers.tactile_hexapod import experiment as th
    from hexhil.papers.tactile_hexapod.grnn.dataset import build_one
    from hexhil.protocol import hexapod

    times = []
    for gait, periods, seed in BUILD_RUNS:
        spec = th.RunSpec("with", gait, 1.0, True, seed, "low", "small", periods)
        facts, _ = build_one((spec, hexapod.GAIT_SPEED_M_S[gait], str(tmp)))
        times.append(facts["build_s"])
    return Row("grnn: dataset build time per run", statistics.mean(times), "s", "",
               "run with trace + rows, d = 1 m, real model, in process: "
               + ", ".join(f"{g} {n} periods {t:.1f} s" for (g, n, _), t in zip(BUILD_RUNS, times)))


def run() -> list[Row]:
    with tempfile.TemporaryDirectory() as tmp:
        rows = _training_and_inference(Path(tmp))
        rows.append(_dataset_build(Path(tmp)))
    return rows
