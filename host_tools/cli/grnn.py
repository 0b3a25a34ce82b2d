"""``hexhil grnn dataset|train|eval|closed-loop``: seed 003's GRNN positional-error predictor
(Sec. 2.6) and the navigator that walks to the goal with it.

torch is imported by the handlers only, so the rest of ``hexhil`` never loads it.
"""
from __future__ import annotations

import argparse

from host_tools.cli import JSON_HELP


def _dataset(args: argparse.Namespace) -> int:
    from host_tools.grnn import dataset

    return dataset.run(args)


def _train(args: argparse.Namespace) -> int:
    from host_tools.grnn import train

    return train.run(args)


def _eval(args: argparse.Namespace) -> int:
    from host_tools.grnn import evaluate

    return evaluate.run(args)


def _closed_loop(args: argparse.Namespace) -> int:
    from host_tools.grnn import closed_loop

    return closed_loop.run(args)


def register(sub: argparse._SubParsersAction) -> None:
    from host_tools.grnn import closed_loop, dataset

    p = sub.add_parser("grnn", help="GRNN positional-error predictor (seed 003 Sec. 2.6)")
    kinds = p.add_subparsers(dest="grnn", metavar="STAGE", parser_class=type(p))
    q = kinds.add_parser("dataset", help="build the training data from traced runs")
    dataset.add_arguments(q)
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
    closed_loop.add_arguments(q)
    q.set_defaults(func=_closed_loop)
