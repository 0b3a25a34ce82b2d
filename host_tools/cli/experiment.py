"""``hexhil experiment NAME``: reproduce a paper's experiments.

Each experiment is a module (under ``host_tools.experiments``); adding one is one line in
``EXPERIMENTS`` (name -> (module, help)). The module defines ``add_arguments(parser)`` and
``run(args) -> int``; heavy imports (MuJoCo, matplotlib) stay inside ``run``.
"""
from __future__ import annotations

import argparse
import importlib

EXPERIMENTS: dict[str, tuple[str, str]] = {
    "tactile-hexapod": ("host_tools.experiments.tactile_hexapod",
                        "seed 003: positional error with and without tactile step switching"),
    "force-sensing": ("host_tools.experiments.force_sensing", "seed 000: beam force sensing, planning, control vs the paper"),
}


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("experiment", help="reproduce a paper's experiments")
    exp = p.add_subparsers(dest="experiment", metavar="EXPERIMENT", parser_class=type(p))
    for name, (module, help_text) in EXPERIMENTS.items():
        try:
            mod = importlib.import_module(module)
        except ModuleNotFoundError as exc:
            if exc.name != module:
                raise
            continue  # experiment not built yet
        q = exp.add_parser(name, help=help_text, description=help_text)
        mod.add_arguments(q)
        q.set_defaults(func=mod.run)
