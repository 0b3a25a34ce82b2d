"""``hexhil grnn train``: the GRNN trained as Sec. 2.6 says (Adam, learning rate 0.001, 50
epochs), deterministically: seeded, one thread, deterministic kernels, so the same data
gives byte-identical weights.

The loss is the MSE of the normalised per-leg errors over every step of the rollout that
evaluation asks for: the known path X teacher-forced, the future path P fed back (Fig. 8).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hexhil.hil.scenario import check_seed
from hexhil.extras import require

require("torch")   # before torch itself: a missing extra is one line, not a traceback
import torch  # noqa: E402

from hexhil.papers.tactile_hexapod.grnn import data as data_mod
from hexhil.papers.tactile_hexapod.grnn.features import LEGS, M_MAX, known_steps
from hexhil.papers.tactile_hexapod.grnn.model import GRNN, Norm, save
from hexhil.progress import Progress, report
from hexhil.protocol.errors import BadFile, BadValue

LEARNING_RATE = 0.001   # Sec. 2.6
BATCH = 4               # sequences per Adam step (the paper is silent; 24 walks -> 6 a epoch)
STD_FLOOR = 1e-6        # a constant column (e.g. one gait only) is centred, not scaled


def fit_norm(ds: data_mod.Dataset) -> Norm:
    """Normalisation from the training rows only."""
    s = np.concatenate([w.sensing for w in ds.sequences])
    e = np.concatenate([w.error_m for w in ds.sequences])
    s_std = s.std(axis=0)
    e_std = e.std(axis=0)
    return Norm(s.mean(axis=0).tolist(), np.where(s_std > STD_FLOOR, s_std, 1.0).tolist(),
                e.mean(axis=0).tolist(), np.where(e_std > STD_FLOOR, e_std, 1.0).tolist())


def rollout_length(walk: data_mod.Walk, periods: int) -> int:
    """The rows a walk is rolled out over: the known path plus at most M_MAX future steps."""
    return min(len(walk.step), known_steps(periods) + M_MAX)


def tensors(ds: data_mod.Dataset, norm: Norm) -> dict[str, torch.Tensor]:
    """Padded, normalised batch of every walk: sensing, error, n_known, mask, error0."""
    lens = [rollout_length(w, int(r["periods"])) for w, r in zip(ds.sequences, ds.runs)]
    t_len = max(lens)
    n_s = len(norm.sensing_mean)
    sens = np.zeros((len(lens), t_len, n_s), dtype=np.float32)
    err = np.zeros((len(lens), t_len, LEGS), dtype=np.float32)
    mask = np.zeros((len(lens), t_len), dtype=np.float32)
    s_mean, s_std = np.asarray(norm.sensing_mean), np.asarray(norm.sensing_std)
    e_mean, e_std = np.asarray(norm.error_mean_m), np.asarray(norm.error_std_m)
    for i, (w, n) in enumerate(zip(ds.sequences, lens)):
        sens[i, :n] = (w.sensing[:n] - s_mean) / s_std
        err[i, :n] = (w.error_m[:n] - e_mean) / e_std
        mask[i, :n] = 1.0
    n_known = [known_steps(int(r["periods"])) for r in ds.runs]
    return {"sensing": torch.from_numpy(sens), "error": torch.from_numpy(err),
            "mask": torch.from_numpy(mask), "n_known": torch.tensor(n_known),
            "error0": torch.from_numpy((-e_mean / e_std).astype(np.float32))}


def masked_mse(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    return (((pred - target) ** 2).sum(dim=2) * mask).sum() / (mask.sum() * LEGS)


def fit(ds: data_mod.Dataset, epochs: int = 50, seed: int = 0, batch: int = BATCH,
        progress: Progress | None = None) -> tuple[GRNN, Norm, list[float], float]:
    """Train; returns the model, its normalisation, the loss per epoch and s per epoch.
    Each epoch done is reported to ``progress`` with its loss."""
    if epochs < 1:
        raise BadValue(f"epochs must be at least 1, got {epochs}", params=("epochs",))
    if not ds.sequences or not any(len(w.step) for w in ds.sequences):
        raise BadValue("the dataset has no steps to train on")
    torch.manual_seed(seed)
    torch.set_num_threads(1)
    torch.use_deterministic_algorithms(True)
    norm = fit_norm(ds)
    t = tensors(ds, norm)
    model = GRNN(len(norm.sensing_mean))
    opt = torch.optim.Adam(model.parameters(), lr=LEARNING_RATE)
    gen = torch.Generator().manual_seed(seed)
    n = t["sensing"].shape[0]
    losses: list[float] = []
    t0 = time.perf_counter()
    report(progress, "epochs", 0, epochs)
    for epoch in range(epochs):
        total = 0.0
        for idx in torch.randperm(n, generator=gen).split(batch):
            pred = model(t["sensing"][idx], t["error"][idx], t["n_known"][idx], t["error0"])
            loss = masked_mse(pred, t["error"][idx], t["mask"][idx])
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += loss.item() * len(idx)
        losses.append(total / n)
        report(progress, "epochs", epoch + 1, epochs, f"loss={losses[-1]:.4f}")
    return model, norm, losses, (time.perf_counter() - t0) / epochs


def run_facts(ds: data_mod.Dataset) -> dict[str, Any]:
    """What evaluation needs from the training runs: their terrain seeds, the constant
    baseline (mean dx) and, per gait, the mean walk between the last step's row and the end
    of the run ("tail": the row is taken when the last lift-off is counted, the run ends
    when the period does)."""
    tails: dict[str, list[float]] = {}
    for r, w in zip(ds.runs, ds.sequences):
        if len(w.body_x_m):
            tails.setdefault(r["gait"], []).append(r["x_end_m"] - float(w.body_x_m[-1]))
    return {"terrain_seeds": sorted({int(r["terrain_seed"]) for r in ds.runs}),
            "mean_dx_m": float(np.mean([r["dx_m"] for r in ds.runs])),
            "tail_m": {g: float(np.mean(v)) for g, v in sorted(tails.items())}}


@dataclass(frozen=True)
class TrainResult:
    """What a training run wrote and how it went."""
    model: str              # the model file
    epochs: int
    final_loss: float       # training MSE of the last epoch (normalised)
    s_per_epoch: float
    runs: int               # walks trained on


def main(data: str, out: str, epochs: int = 50, seed: int = 0,
         progress: Progress | None = None) -> TrainResult:
    """Train on ``data`` (dataset.npz or its folder) and write the model file ``out``."""
    check_seed(seed, "seed", params=("seed",))
    if not Path(out).parent.is_dir():
        raise BadFile(f"out {out}: no folder {Path(out).parent}", params=("out",))
    ds = data_mod.read(data)
    model, norm, losses, s_per_epoch = fit(ds, epochs, seed, progress=progress)
    meta = {"dataset": {k: v for k, v in ds.meta.items() if k != "runs"},
            "train_runs": ds.runs, "epochs": epochs, "seed": seed, "batch": BATCH,
            "learning_rate": LEARNING_RATE, "loss": losses, **run_facts(ds)}
    save(out, model, norm, meta)
    return TrainResult(out, epochs, losses[-1], s_per_epoch, len(ds.runs))
