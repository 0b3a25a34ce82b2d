"""``hexhil experiment NAME``: reproduce a paper's experiments.

Each experiment is a library module (under ``host_tools.experiments``) whose ``main`` runs
it and writes its report; here each gets its options and its handler, and one line in
``EXPERIMENTS`` (name -> (help, add_arguments, handler)). Heavy imports (MuJoCo,
matplotlib) stay inside the handlers.
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Callable

from hil.link import IN_PROCESS, RUNTIMES
from hil.world.fidelity import OBSTACLE_BODIES, OBSTACLE_BODY
from host_tools.cli import ProgressBar, emit, emit_json
from protocol.errors import UserError


def _out_folder(path: str) -> Path:
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out} exists and is not a folder")
    return out


def _tactile_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--quick", action="store_true",
                   help="reduced sweep: 1 m only, one seed per case (a few minutes on 2 cores)")
    p.add_argument("--out", default="out/tactile-hexapod", help="output folder (table, plots, JSON)")
    p.add_argument("--workers", type=int, default=max(1, os.cpu_count() or 1),
                   help="local worker processes (default: one per core)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on a Dask distributed cluster, e.g. tcp://127.0.0.1:8786")
    p.add_argument("--seeds", type=int, default=None,
                   help="terrains per case (default 1 with --quick, 3 otherwise)")
    p.add_argument("--traces", action="store_true",
                   help="record every run to an MCAP trace in OUT/traces")
    p.add_argument("--model", choices=("real", "ideal"), default="real",
                   help="world model: real (servo backlash and spread, trial noise; default) "
                        "or ideal (the regression world of scenario files)")
    p.add_argument("--obstacles", choices=OBSTACLE_BODIES, default=OBSTACLE_BODY,
                   help="with the real model: obstacles fixed to the ground (default, as the "
                        "paper's held) or loose wooden ones")
    p.add_argument("--python", choices=(IN_PROCESS, *RUNTIMES), default=IN_PROCESS,
                   help="firmware runtime: in this process (default; the same serial digest "
                        "as micropython, without two process wake-ups a link round trip), or a "
                        "child process under micropython (the reference) or cpython")
    p.add_argument("--json", action="store_true", help="print a JSON summary as the last line")


def _tactile(args: argparse.Namespace) -> int:
    from host_tools.experiments import tactile_hexapod
    from host_tools.experiments.executor import Executor

    seeds = args.seeds if args.seeds is not None else (1 if args.quick else 3)
    if seeds < 1:
        raise UserError(f"--seeds must be at least 1, got {seeds}")
    out = _out_folder(args.out)
    res = tactile_hexapod.main(args.quick, out, seeds,
                               Executor(args.workers, args.scheduler, ProgressBar("run")),
                               args.traces, args.model, args.obstacles, args.python)
    print(Path(res["table"]).read_text())
    print(f"wrote {res['table']} and {len(res['plots'])} plots in {res['out']} "
          f"({res['runs']} runs, {res['wall_s']:.0f} s)")
    if args.json:
        emit_json(res)
    return 0


def _force_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--quick", action="store_true", help="5 seeds and a 4 mm / 5 deg landscape grid (minutes)")
    p.add_argument("--out", default="out/force-sensing", help="output folder (force-sensing.md and PNGs)")
    p.add_argument("--seeds", type=int,
                   help="noise seeds 0..N-1 for the tables and the rig (default 20, 5 with --quick)")
    p.add_argument("--json", action="store_true", help="print a JSON summary as the last line")


def _force(args: argparse.Namespace) -> int:
    from host_tools.experiments import force_sensing

    out = _out_folder(args.out)
    if args.seeds is not None and args.seeds < 1:
        raise UserError(f"--seeds must be at least 1, got {args.seeds}")
    try:
        summary = force_sensing.main(args.quick, out, args.seeds)
    except OSError as exc:
        raise UserError(f"cannot write into {out}: {exc.strerror}") from None
    emit(args, summary, f"report: {summary['report']} ({summary['wall_s']:.0f} s)")
    return 0


Handler = Callable[[argparse.Namespace], int]
EXPERIMENTS: dict[str, tuple[str, Callable[[argparse.ArgumentParser], None], Handler]] = {
    "tactile-hexapod": ("seed 003: positional error with and without tactile step switching",
                        _tactile_arguments, _tactile),
    "force-sensing": ("seed 000: beam force sensing, planning, control vs the paper",
                      _force_arguments, _force),
}


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("experiment", help="reproduce a paper's experiments")
    exp = p.add_subparsers(dest="experiment", metavar="EXPERIMENT", parser_class=type(p))
    for name, (help_text, add_arguments, handler) in EXPERIMENTS.items():
        q = exp.add_parser(name, help=help_text, description=help_text)
        add_arguments(q)
        q.set_defaults(func=handler)
