"""``hexhil grnn dataset|train|eval|closed-loop``: seed 003's GRNN positional-error predictor
(Sec. 2.6) and the navigator that walks to the goal with it.

torch is imported by the handlers only, so the rest of ``hexhil`` never loads it.
"""
from __future__ import annotations

import argparse
import os
from dataclasses import asdict
from pathlib import Path

from hexhil.hil.scenario.world_section import OBSTACLE_BODIES, OBSTACLE_BODY
from hexhil.cli import JSON_HELP, actions, emit, emit_json, ProgressBar
from hexhil.protocol.errors import BadValue

WORKERS = max(1, os.cpu_count() or 1)


def _dataset(args: argparse.Namespace) -> int:
    from hexhil.papers.tactile_hexapod.grnn import dataset

    opts = dataset.DatasetOptions(tuple(args.traces), args.terrains, args.seed, args.distance,
                                  args.obstacles, args.workers)
    res = dataset.build(Path(args.out), opts, ProgressBar("run"))
    times = res.build_s_per_run
    for i, s in enumerate(times):
        print(f"run {i + 1}/{len(times)}: {s:.1f} s")
    print(f"wrote {res.dataset} ({res.runs} runs, {res.rows} steps) in "
          f"{res.wall_s:.0f} s; build time per run: median "
          f"{sorted(times)[len(times) // 2]:.1f} s")
    if args.json:
        emit_json(asdict(res))
    return 0


def _train(args: argparse.Namespace) -> int:
    from hexhil.papers.tactile_hexapod.grnn import train

    r = train.main(args.data, args.out, args.epochs, args.seed, ProgressBar("epoch"))
    emit(args, asdict(r), f"wrote {r.model}: {r.epochs} epochs on {r.runs} walks, final loss "
                          f"{r.final_loss:.4f}, {r.s_per_epoch:.3f} s/epoch")
    return 0


def _eval(args: argparse.Namespace) -> int:
    from hexhil.papers.tactile_hexapod.grnn import held_out_report

    res = held_out_report.write_report(args.model, args.data, Path(args.out))
    print(held_out_report.markdown(res))
    print(f"wrote {res['table']} and {len(res['plots'])} plots")
    if args.json:
        emit_json(res)
    return 0


def _closed_loop(args: argparse.Namespace) -> int:
    from hexhil.papers.tactile_hexapod.grnn import navigator_trials

    if args.workers < 1:
        raise BadValue(f"--workers must be at least 1, got {args.workers}")
    res = navigator_trials.closed_loop(args.model, args.data, args.workers, ProgressBar("run"))
    print(navigator_trials.markdown(res), end="")
    if args.out:
        navigator_trials.write(res, Path(args.out))
    a = res["arms"]
    print(f"mean relative goal error: tactile only {100 * a['planned']['mean_rel_error']:.1f} %, "
          f"+ Eq. 8-14 navigator {100 * a['model']['mean_rel_error']:.1f} %, "
          f"+ GRNN navigator {100 * a['grnn']['mean_rel_error']:.1f} %")
    if args.json:
        emit_json(res)
    return 0


def _dataset_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("traces", nargs="*", metavar="MCAP", help="read these traces instead of "
                   "running the sweep")
    p.add_argument("--out", required=True, help="output folder (dataset.npz, dataset.json)")
    p.add_argument("--terrains", type=int, default=32, help="terrain seeds to run (default 32)")
    p.add_argument("--seed", type=int, default=1, help="first terrain seed (default 1)")
    p.add_argument("--distance", type=float, default=1.0, metavar="M",
                   help="goal distance d in m (default 1, as the paper's runs)")
    p.add_argument("--obstacles", choices=OBSTACLE_BODIES, default=OBSTACLE_BODY,
                   help="obstacles fixed to the ground (default: the paper's robot cannot shove "
                        "its obstacles aside) or loose wooden ones")
    p.add_argument("--workers", type=int, default=WORKERS,
                   help="local worker processes (default: one per core)")
    p.add_argument("--json", action="store_true", help=JSON_HELP)


def _closed_loop_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("model", help="the GRNN (hexhil grnn train)")
    p.add_argument("data", help="a dataset of terrains the model never saw (hexhil grnn dataset)")
    p.add_argument("--out", help="write closed_loop.json and closed_loop.md into this folder")
    p.add_argument("--workers", type=int, default=WORKERS,
                   help="local worker processes (default: one per core)")
    p.add_argument("--json", action="store_true", help=JSON_HELP)


def register(sub: argparse._SubParsersAction) -> None:
    kinds = actions(sub, "grnn", "GRNN positional-error predictor (seed 003 Sec. 2.6)",
                        "STAGE")
    q = kinds.add_parser("dataset", help="build the training data from traced runs")
    _dataset_arguments(q)
    q.set_defaults(func=_dataset)
    q = kinds.add_parser("train", help="train the GRNN on a dataset")
    q.add_argument("data", help="dataset.npz (or its folder)")
    q.add_argument("--out", required=True, help="model file to write (model.pt)")
    q.add_argument("--epochs", type=int, default=50, help="epochs (default 50, Sec. 2.6)")
    q.add_argument("--seed", type=int, default=0, help="torch seed (default 0)")
    q.add_argument("--json", action="store_true", help=JSON_HELP)
    q.set_defaults(func=_train)
    q = kinds.add_parser("eval", help="predicted vs measured dx on held-out terrains")
    q.add_argument("model", help="model file from 'hexhil grnn train'")
    q.add_argument("data", help="held-out dataset.npz (or its folder)")
    q.add_argument("--out", default="out/grnn-eval", help="folder for the table and PNGs")
    q.add_argument("--json", action="store_true", help=JSON_HELP)
    q.set_defaults(func=_eval)
    q = kinds.add_parser("closed-loop", help="held-out terrains walked three ways: tactile only, "
                         "+ Eq. 8-14 navigator, + GRNN navigator")
    _closed_loop_arguments(q)
    q.set_defaults(func=_closed_loop)
