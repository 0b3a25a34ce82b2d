"""``hexhil grnn closed-loop``: the tactile-hexapod experiment's with-method runs on a
dataset's terrains, three ways (beyond the paper):

* tactile only: the planned steps and no more, as in the paper (Sec. 3.3), stopped by the
  same ``gait_command`` as the navigated arms;
* tactile + the Eq. 8-14 navigator (``--navigator model``);
* tactile + the GRNN navigator (``--navigator grnn``).

Same terrains, seeds, world and calibrated step counts for all three, so the goal errors
pair up. Meant for terrains the model never saw (the eval's held-out dataset); the model's
training seeds are refused.
"""
from __future__ import annotations

import json
from pathlib import Path
from statistics import mean
from typing import Any

from hexhil.hil.scenario.world_section import OBSTACLE_BODY
from hexhil.papers.tactile_hexapod.grnn import data as data_mod
from hexhil.progress import Progress
from hexhil.protocol.errors import BadValue

ARMS = (("planned", "tactile only"), ("model", "tactile + Eq. 8-14 navigator"),
        ("grnn", "tactile + GRNN navigator"))


def specs(ds: data_mod.Dataset, model_path: str) -> list[tuple[Any, float]]:
    """(RunSpec, calibrated speed) for every run of ``ds`` and every arm."""
    from hexhil.papers.tactile_hexapod import experiment as th

    speed = ds.meta.get("probe_speed_m_s")
    if not speed:
        raise BadValue("the dataset holds no calibrated speeds (built from traces?): "
                       "closed-loop runs need one made by 'hexhil grnn dataset' itself")
    world = ds.meta.get("world", {})
    out = []
    for r in ds.runs:
        for nav, _ in ARMS:
            spec = th.RunSpec("with", r["gait"], r["distance_m"], True, int(r["terrain_seed"]),
                              r["density"], r["height_class"], int(r["periods"]),
                              world.get("model", "real"), world.get("obstacle_body", OBSTACLE_BODY),
                              nav, model_path if nav == "grnn" else "")
            out.append((spec, float(speed[r["gait"]])))
    return out


def closed_loop(model_path: str, data_path: str, workers: int,
                progress: Progress | None = None) -> dict[str, Any]:
    """Run the three arms; returns per-arm means and the per-case table."""
    from hexhil.executor import Executor
    from hexhil.papers.tactile_hexapod.experiment import run_with_speed
    from hexhil.papers.tactile_hexapod.grnn.model import load

    pred = load(model_path)      # refuses a mismatched model before any run starts
    ds = data_mod.read(data_path)
    trained = set(int(s) for s in pred.meta.get("terrain_seeds", []))
    seen = sorted(trained & {int(r["terrain_seed"]) for r in ds.runs})
    if seen:
        raise BadValue(f"{data_path}: terrain seeds {seen} were in the model's training set; "
                       f"closed-loop runs need terrains it never saw")
    runs = Executor(workers, progress=progress).map(run_with_speed, specs(ds, model_path),
                                                    "closed-loop runs")
    cases: dict[tuple[int, str], dict[str, Any]] = {}
    for r in runs:
        c = cases.setdefault((r["seed"], r["gait"]), {
            "terrain_seed": r["seed"], "gait": r["gait"], "density": r["density"],
            "height_class": r["height_class"], "periods": r["periods"]})
        arm = r["navigator"]
        c[arm] = {"dx_m": round(r["dx_m"], 4), "dy_m": round(r["dy_m"], 4),
                  "rel_error": round(r["rel_error"], 4),
                  "stop_step": r.get("navigation", {}).get("stop_step")}
    table = sorted(cases.values(), key=lambda c: c["terrain_seed"])
    arms = {}
    for nav, label in ARMS:
        arms[nav] = {"label": label,
                     "mean_rel_error": round(mean(c[nav]["rel_error"] for c in table), 4),
                     "mean_abs_dx_m": round(mean(abs(c[nav]["dx_m"]) for c in table), 4),
                     "mean_abs_dy_m": round(mean(abs(c[nav]["dy_m"]) for c in table), 4)}
    base = arms["planned"]["mean_rel_error"]
    return {"model": model_path, "data": data_path, "cases": table, "arms": arms,
            "grnn_over_tactile": round(arms["grnn"]["mean_rel_error"] / base, 3)
            if base else None}


def markdown(res: dict[str, Any]) -> str:
    lines = ["| terrain | gait | terrain class | planned steps | "
             + " | ".join(label for _, label in ARMS) + " |",
             "|---|---|---|---|" + "---|" * len(ARMS)]
    for c in res["cases"]:
        cells = []
        for nav, _ in ARMS:
            a = c[nav]
            stop = f", {a['stop_step']} steps" if a["stop_step"] is not None else ""
            cells.append(f"{100 * a['rel_error']:.1f} % (dx {100 * a['dx_m']:+.1f} cm{stop})")
        lines.append(f"| {c['terrain_seed']} | {c['gait']} | {c['density']}-{c['height_class']} "
                     f"| {c['periods']} | " + " | ".join(cells) + " |")
    lines.append("| **mean** | | | | " + " | ".join(
        f"**{100 * res['arms'][nav]['mean_rel_error']:.1f} %**" for nav, _ in ARMS)
        + " |")
    return "\n".join(lines) + "\n"


def write(res: dict[str, Any], out: Path) -> None:
    """closed_loop.json and closed_loop.md into the folder ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "closed_loop.json").write_text(json.dumps(res, indent=1, sort_keys=True) + "\n")
    (out / "closed_loop.md").write_text(markdown(res))
