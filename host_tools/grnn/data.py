"""The GRNN dataset file: ``dataset.npz`` (sequences and the run table, no pickles) with
its metadata also inside, and ``dataset.json`` beside it for people. Read by ``train``
and ``evaluate``; written by ``dataset``. No torch.
"""
from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from host_tools.grnn.features import FEATURE_VERSION, LEGS, SENSING, StepRow
from protocol.errors import UserError

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
        raise UserError(f"{p}: no such dataset file")
    try:
        with np.load(p, allow_pickle=False) as z:
            a = {k: z[k] for k in z.files}
        meta = json.loads(str(a["meta_json"]))
        offsets = a["offsets"]
        runs = [{k: (str(a[f"run_{k}"][i]) if k in RUN_TEXT else float(a[f"run_{k}"][i]))
                 for k in RUN_TEXT + RUN_NUMBERS} for i in range(len(offsets) - 1)]
    except (OSError, ValueError, KeyError, zipfile.BadZipFile, json.JSONDecodeError) as exc:
        raise UserError(f"{p}: not a GRNN dataset ({type(exc).__name__})") from None
    if meta.get("feature_version") != FEATURE_VERSION or tuple(meta.get("sensing", ())) != SENSING:
        raise UserError(f"{p}: dataset features {meta.get('feature_version')!r} do not match "
                        f"this code's {FEATURE_VERSION!r}; rebuild it with 'hexhil grnn dataset'")
    seqs = [Walk(*(a[k][lo:hi] for k in ("step", "t_us", "planned_x_m", "body_x_m",
                                                "sensing", "error_m")))
            for lo, hi in zip(offsets[:-1], offsets[1:])]
    return Dataset(runs, seqs, meta)
