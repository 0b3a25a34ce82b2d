"""``hexhil experiment NAME``: reproduce a paper's experiments.

Each experiment is a library module (under ``hexhil.papers``) whose ``main`` runs
it and writes its report; here each gets its options and its handler, and one line in
``EXPERIMENTS`` (name -> (help, add_arguments, handler)). Heavy imports (MuJoCo,
matplotlib) stay inside the handlers.
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any, Callable

from hexhil.hil.link.firmware_process import IN_PROCESS, RUNTIMES
from hexhil.hil.scenario.world_section import OBSTACLE_BODIES, OBSTACLE_BODY
from hexhil.cli import JSON_HELP, actions, emit_json, ProgressBar
from hexhil.protocol.errors import BadFile, BadValue, UserError

MAX_SEEDS = 1000   # seeds of one sweep: more is a typo, not days of runs


def _out_folder(path: str) -> Path:
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise BadFile(f"--out {out} exists and is not a folder")
    return out


def _show(args: argparse.Namespace, headline: str, lines: list[str], report: str,
          figures: list[str], summary: dict[str, Any]) -> None:
    """Every experiment's output, one style: what ran, its headline figures, where the
    report and the figures are (the Markdown report stays in its file); with ``--json``
    the summary as the last line."""
    print(headline)
    for line in lines:
        print(f"  {line}")
    print(f"report: {report}")
    print(f"figures: {', '.join(Path(f).name for f in figures)} (in {Path(report).parent})")
    if args.json:
        emit_json(summary)


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
    p.add_argument("--runtime", "--python", dest="python", choices=(IN_PROCESS, *RUNTIMES),
                   default=IN_PROCESS, help="firmware runtime: in this process (default; the same serial digest "
                        "as micropython, without two process wake-ups a link round trip), or a "
                        "child process under micropython (the reference) or cpython")
    p.add_argument("--json", action="store_true", help=JSON_HELP)


def _tactile(args: argparse.Namespace) -> int:
    from hexhil.papers.tactile_hexapod import experiment as tactile_hexapod
    from hexhil.executor import Executor

    seeds = args.seeds if args.seeds is not None else (1 if args.quick else 3)
    if not 1 <= seeds <= MAX_SEEDS:
        raise BadValue(f"--seeds must be 1-{MAX_SEEDS}, got {seeds}")
    out = _out_folder(args.out)
    opts = tactile_hexapod.SweepOptions(args.quick, seeds, args.traces, args.model,
                                        args.obstacles, args.python)
    res = tactile_hexapod.main(out, opts, Executor(args.workers, args.scheduler,
                                                   ProgressBar("run")))
    wins, cases = res["wave_wins"]
    nearer, pairs = res["paired_nearer_with_method"]
    _show(args, f"tactile-hexapod: {'quick' if args.quick else 'full'} sweep, {res['runs']} runs "
                f"in {res['wall_s']:.0f} s",
          [f"mean relative goal error: {100 * res['rel_error_without']:.1f} % without the "
           f"method, {100 * res['rel_error_with']:.1f} % with it ({res['improvement']:.2f}x)",
           f"with the method nearer the goal on the same terrain: {nearer} of {pairs} pairs; "
           f"wave nearer than tripod: {wins} of {cases} cases"],
          res["table"], res["plots"], res)
    return 0


def _force_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--quick", action="store_true", help="5 seeds and a 4 mm / 5 deg landscape grid (minutes)")
    p.add_argument("--out", default="out/force-sensing", help="output folder (force-sensing.md and PNGs)")
    p.add_argument("--seeds", type=int,
                   help="noise seeds 0..N-1 for the tables and the rig (default 20, 5 with --quick)")
    p.add_argument("--json", action="store_true", help=JSON_HELP)


def _force(args: argparse.Namespace) -> int:
    from hexhil.papers.beam_traversal import force_sensing

    out = _out_folder(args.out)
    if args.seeds is not None and not 1 <= args.seeds <= MAX_SEEDS:
        raise BadValue(f"--seeds must be 1-{MAX_SEEDS}, got {args.seeds}")
    try:
        summary = force_sensing.main(args.quick, out, args.seeds)
    except UserError:   # a BadFile is an OSError too: already one line
        raise
    except OSError as exc:
        raise BadFile(f"cannot write into {out}: {exc.strerror}") from None
    modes = ", ".join(f"k = {k} {m}" for k, m in summary["modes"].items())
    energy = summary["energy_mJ"]
    interact_avoid = "; ".join(
        f"k = {k} interact {energy[f'interact/{k}/300']:.1f} vs avoid {energy[f'avoid/{k}']:.1f}"
        for k in summary["modes"] if f"interact/{k}/300" in energy and f"avoid/{k}" in energy)
    worse = summary["worse_than_paper"]
    _show(args, f"force-sensing: {'quick' if args.quick else 'full'}, {summary['seeds']} noise "
                f"seeds, in {summary['wall_s']:.0f} s",
          [f"planned modes: {modes}; k0 = {summary['k0']:.4f} N m/rad, crossover k = "
           f"{summary['crossover_k']:.3f}",
           *([f"energy at 300 ms delay (mJ): {interact_avoid}"] if interact_avoid else []),
           f"estimation errors above the paper's: {len(worse)} table cells (listed in the report)"
           if worse else "estimation errors: none above the paper's"],
          summary["report"], summary["figures"], summary)
    return 0


Handler = Callable[[argparse.Namespace], int]
EXPERIMENTS: dict[str, tuple[str, Callable[[argparse.ArgumentParser], None], Handler]] = {
    "tactile-hexapod": ("seed 003: positional error with and without tactile step switching",
                        _tactile_arguments, _tactile),
    "force-sensing": ("seed 000: beam force sensing, planning, control vs the paper",
                      _force_arguments, _force),
}


def register(sub: argparse._SubParsersAction) -> None:
    exp = actions(sub, "experiment", "reproduce a paper's experiments", "EXPERIMENT")
    for name, (help_text, add_arguments, handler) in EXPERIMENTS.items():
        q = exp.add_parser(name, help=help_text, description=help_text)
        add_arguments(q)
        q.set_defaults(func=handler)
