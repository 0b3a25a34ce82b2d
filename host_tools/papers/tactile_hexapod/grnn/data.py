"""The GRNN dataset file: ``dataset.npz`` (sequences and the run table, no pickles) with
its metadata also inside, and ``dataset.json`` beside it for people. Read by ``train``
and ``evaluate``; written by ``dataset``. No torch.
"""
from __future__ import annotations

import json
import math
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hexhil.papers.tactile_hexapod.grnn.features import (DEFINITIONS, FEATURE_VERSION, KNOWN_FRACTION, LEGS,
                                      M_MAX, SENSING, StepRow)
from hexhil.protocol.errors import BadFile, BadValue

# per-run columns of the run table (strings and numbers), in the npz and the sidecar
RUN_TEXT = ("gait", "density", "height_class", "source")
RUN_NUMBERS = ("terrain_seed", "distance_m", "periods", "dx_m", "model_dx_m", "x_end_m")


@dataclass
class Walk:
    """One run's rows as arrays (lengths in m, times in us)."""

    step: np.ndarray          # (T,) int
    t_us: np.ndarray          # (T,) int
    planned_x_m: np.ndarray   # (T,)
    body_x_m: np.ndarray      # (T,)
    sensing: np.ndarray       # (T, len(SENSING))
    error_m: np.ndarray       # (T, 6)


@dataclass
class Dataset:
    runs: list[dict[str, Any]]      # run table: RUN_TEXT + RUN_NUMBERS per run
    sequences: list[Walk]       # same order
    meta: dict[str, Any]            # the sidecar's content


def feature_meta() -> dict[str, Any]:
    """The feature definition a dataset was built with (checked on reading)."""
    return {"feature_version": FEATURE_VERSION, "sensing": list(SENSING),
            "definitions": DEFINITIONS, "known_fraction": KNOWN_FRACTION, "m_max": M_MAX}


def write(out_dir: Path, runs: list[dict[str, Any]], rows: list[list[StepRow]],
          meta: dict[str, Any]) -> Path:
    """Write ``out_dir/dataset.npz`` and ``out_dir/dataset.json``; returns the npz path."""
    flat = [r for seq in rows for r in seq]
    offsets = np.cumsum([0] + [len(seq) for seq in rows])
    meta = dict(meta, runs=runs)
    arrays: dict[str, np.ndarray] = {
        "offsets": offsets.astype(np.int64),
        "step": np.array([r.step for r in flat], dtype=np.int64),
        "t_us": np.array([r.t_us for r in flat], dtype=np.int64),
        "planned_x_m": np.array([r.planned_x_m for r in flat], dtype=np.float64),
        "body_x_m": np.array([r.body_x_m for r in flat], dtype=np.float64),
        "sensing": np.array([r.sensing for r in flat], dtype=np.float64).reshape(-1, len(SENSING)),
        "error_m": np.array([r.error_m for r in flat], dtype=np.float64).reshape(-1, LEGS),
        "meta_json": np.array(json.dumps(meta, sort_keys=True)),
    }
    for k in RUN_TEXT:
        arrays[f"run_{k}"] = np.array([str(r[k]) for r in runs], dtype=str)
    for k in RUN_NUMBERS:
        arrays[f"run_{k}"] = np.array([float(r[k]) for r in runs], dtype=np.float64)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "dataset.npz"
    np.savez_compressed(path, **arrays)
    (out_dir / "dataset.json").write_text(json.dumps(meta, indent=1, sort_keys=True) + "\n")
    return path


def read(path: str | Path) -> Dataset:
    """A dataset file (or the folder holding ``dataset.npz``), checked against this code's
    features; one-line ``UserError`` otherwise."""
    p = Path(path)
    if p.is_dir():
        p = p / "dataset.npz"
    if not p.is_file():
        raise BadFile(f"{p}: no such dataset file")
    try:
        with np.load(p, allow_pickle=False) as z:
            a = {k: z[k] for k in z.files}
        meta = json.loads(str(a["meta_json"]))
        offsets = a["offsets"]
        runs = [{k: (str(a[f"run_{k}"][i]) if k in RUN_TEXT else float(a[f"run_{k}"][i]))
                 for k in RUN_TEXT + RUN_NUMBERS} for i in range(len(offsets) - 1)]
    except (OSError, ValueError, KeyError, zipfile.BadZipFile, json.JSONDecodeError) as exc:
        raise BadValue(f"{p}: not a GRNN dataset ({type(exc).__name__})") from None
    if meta.get("feature_version") != FEATURE_VERSION or tuple(meta.get("sensing", ())) != SENSING:
        raise BadValue(f"{p}: dataset features {meta.get('feature_version')!r} do not match "
                       f"this code's {FEATURE_VERSION!r}; rebuild it with 'hexhil grnn dataset'")
    seqs = [Walk(*(a[k][lo:hi] for k in ("step", "t_us", "planned_x_m", "body_x_m",
                                                "sensing", "error_m")))
            for lo, hi in zip(offsets[:-1], offsets[1:])]
    return Dataset(runs, seqs, meta)


def synthetic(walks: int, seed: int = 0, first_terrain_seed: int = 1
              ) -> tuple[list[dict[str, Any]], list[list[StepRow]]]:
    """Walks that need no simulator, for the tests and the bench: the body falls short of
    the plan by a gait-specific slip plus 2 cm for every switch hit, so an error grows with
    what the robot senses and a constant cannot follow it. Realistic sizes: 15-30 steps."""
    from hexhil.papers.tactile_hexapod.grnn.features import hip_errors_m

    rng = np.random.default_rng(seed)
    runs, rows = [], []
    for i in range(walks):
        gait = ("tripod", "wave")[i % 2]
        step_m = 0.1 if gait == "tripod" else 0.06
        slip = 0.85 if gait == "tripod" else 0.9
        n, p_hit = int(rng.integers(15, 31)), float(rng.uniform(0.02, 0.25))
        x = y = yaw = 0.0
        walk: list[StepRow] = []
        over = np.zeros(LEGS)
        for k in range(1, n + 1):
            hits = (rng.random(LEGS) < p_hit).astype(float)
            x += step_m * slip - 0.02 * hits.sum() + rng.normal(0, 0.002)
            yaw += 0.01 * (hits[:3].sum() - hits[3:].sum())
            feet = rng.normal(0.0, 0.005, 2 * LEGS) + np.repeat([0.18, -0.08], LEGS)
            sensing = [*hits, *over, *feet, step_m]
            walk.append(StepRow(k, int(k * 2e6), k * step_m, x, y, yaw, [float(v) for v in sensing],
                                hip_errors_m(k * step_m, x, y, yaw)))
            over = hits
        x_end = x + 0.4 * step_m * slip
        d = round(n * step_m * slip, 2)
        runs.append({"gait": gait, "density": "synthetic", "height_class": "", "source": "synthetic",
                     "terrain_seed": first_terrain_seed + i, "distance_m": d, "periods": n,
                     "dx_m": d - x_end, "x_end_m": x_end, "model_dx_m": math.nan})
        rows.append(walk)
    return runs, rows
