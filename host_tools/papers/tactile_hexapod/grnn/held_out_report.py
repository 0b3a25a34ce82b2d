"""``hexhil grnn eval``: the GRNN's predicted dx at the goal on terrains it never saw,
beside the measured dx, the analytic model (Eq. 8-14, ``hexhil.papers.tactile_hexapod.error_model``) and a
constant (the training runs' mean dx).

Per held-out walk: the first n = ceil(KNOWN_FRACTION * N) steps are fed with their measured
errors (the known path X), the rest are rolled out on the model's own output (the future
path P, Fig. 8). The mean over the legs of a hip error is planned_x - body_x, so the
predicted body x at the last step's row is planned_x - mean(predicted error); the row is
taken when the last lift-off is counted, before the run ends, so the training runs' mean
walk from that row to the end of the run (per gait, ``tail_m`` in the model) is added. The
predicted dx = d - that x: the same quantity as the measured dx_m = d - x_end.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from hexhil.papers.tactile_hexapod.grnn import data as data_mod
from hexhil.papers.tactile_hexapod.grnn.features import M_MAX, known_steps
from hexhil.papers.tactile_hexapod.grnn.model import Predictor, load
from hexhil.protocol.errors import BadFile, BadValue


def predict_dx_m(pred: Predictor, walk: data_mod.Walk, run: dict[str, Any]) -> float:
    """The GRNN's dx at the goal for one walk (m)."""
    n = known_steps(int(run["periods"]))
    rows = min(len(walk.step), n + M_MAX)
    if rows == 0:
        return math.nan
    pred.reset()
    out: list[float] = []
    for t in range(rows):
        out = pred.step(walk.sensing[t].tolist(), walk.error_m[t].tolist() if t < n else None)
    tails = pred.meta["tail_m"]
    tail = tails.get(run["gait"], float(np.mean(list(tails.values()))))
    x_end = float(walk.planned_x_m[rows - 1]) - float(np.mean(out)) + tail
    return run["distance_m"] - x_end


def _mae(err: list[float]) -> float:
    ok = [abs(e) for e in err if not math.isnan(e)]
    return float(np.mean(ok)) if ok else math.nan


def evaluate(model_path: str, data_path: str) -> dict[str, Any]:
    """Per-case predictions and the three mean absolute errors (m and relative to d)."""
    pred = load(model_path)
    ds = data_mod.read(data_path)
    seen = set(pred.meta["terrain_seeds"]) & {int(r["terrain_seed"]) for r in ds.runs}
    if seen:
        raise BadValue(f"{data_path}: terrain seeds {sorted(seen)} were in the model's "
                       f"training data; evaluate on held-out terrains")
    cases = []
    for w, r in zip(ds.sequences, ds.runs):
        cases.append({"terrain_seed": int(r["terrain_seed"]), "gait": r["gait"],
                      "terrain": f"{r['density']}-{r['height_class']}",
                      "distance_m": r["distance_m"], "periods": int(r["periods"]),
                      "dx_m": r["dx_m"], "grnn_dx_m": predict_dx_m(pred, w, r),
                      "model_dx_m": r["model_dx_m"], "const_dx_m": pred.meta["mean_dx_m"]})
    out: dict[str, Any] = {"cases": cases, "runs": len(cases)}
    d = float(np.mean([c["distance_m"] for c in cases])) if cases else math.nan
    for key, name in (("grnn_dx_m", "grnn"), ("model_dx_m", "eq8_14"), ("const_dx_m", "constant")):
        mae = _mae([c[key] - c["dx_m"] for c in cases])
        out[f"mae_{name}_m"] = mae
        out[f"mae_{name}_rel"] = _mae([(c[key] - c["dx_m"]) / c["distance_m"] for c in cases])
    out["mean_distance_m"] = d
    out["mean_abs_dx_m"] = _mae([c["dx_m"] for c in cases])
    return out


def markdown(res: dict[str, Any]) -> str:
    lines = ["| terrain seed | gait | terrain | N | measured dx (cm) | GRNN (cm) | Eq. 8-14 (cm) "
             "| constant (cm) |", "|---|---|---|---|---|---|---|---|"]
    for c in res["cases"]:
        lines.append(f"| {c['terrain_seed']} | {c['gait']} | {c['terrain']} | {c['periods']} | "
                     f"{100 * c['dx_m']:.1f} | {100 * c['grnn_dx_m']:.1f} | "
                     f"{100 * c['model_dx_m']:.1f} | {100 * c['const_dx_m']:.1f} |")
    lines += ["", "| predictor | MAE of dx (cm) | relative to d |", "|---|---|---|"]
    for name, label in (("grnn", "GRNN"), ("eq8_14", "Eq. 8-14"), ("constant", "constant")):
        lines.append(f"| {label} | {100 * res[f'mae_{name}_m']:.1f} | "
                     f"{100 * res[f'mae_{name}_rel']:.1f} % |")
    return "\n".join(lines) + "\n"


def plots(res: dict[str, Any], losses: list[float], out: Path) -> list[Path]:
    """Loss curve (from the model) and predicted vs measured dx per case."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = [out / "loss.png", out / "predicted_vs_measured.png"]
    fig, ax = plt.subplots(figsize=(5, 3.5))
    ax.plot(range(1, len(losses) + 1), losses)
    ax.set(xlabel="epoch", ylabel="training MSE (normalised)", yscale="log",
           title="GRNN training loss")
    fig.tight_layout()
    fig.savefig(paths[0], dpi=100)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(5, 4.5))
    meas = [100 * c["dx_m"] for c in res["cases"]]
    ax.scatter(meas, [100 * c["grnn_dx_m"] for c in res["cases"]], label="GRNN")
    ax.scatter(meas, [100 * c["model_dx_m"] for c in res["cases"]], marker="x", label="Eq. 8-14")
    lo = min(meas + [0.0])
    hi = max(meas + [1.0])
    ax.plot([lo, hi], [lo, hi], "k:", linewidth=1, label="exact")
    ax.set(xlabel="measured dx (cm)", ylabel="predicted dx (cm)",
           title="dx at the goal, held-out terrains")
    ax.legend()
    fig.tight_layout()
    fig.savefig(paths[1], dpi=100)
    plt.close(fig)
    return paths


def write_report(model_path: str, data_path: str, out: Path) -> dict[str, Any]:
    """``evaluate``, then eval.md and the plots into ``out``; the result names them
    (``table``, ``plots``)."""
    res = evaluate(model_path, data_path)
    if out.exists() and not out.is_dir():
        raise BadFile(f"out {out} exists and is not a folder", params=("out",))
    out.mkdir(parents=True, exist_ok=True)
    (out / "eval.md").write_text(markdown(res))
    res["plots"] = [str(p) for p in plots(res, load(model_path).meta["loss"], out)]
    res["table"] = str(out / "eval.md")
    return res
