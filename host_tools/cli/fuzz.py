"""``hexhil fuzz SCENARIO --expect FILE``: fuzz the firmware through its bus. Faults placed in
virtual time (status packets mangled, late, missing or doubled; switches bouncing or stuck;
CAN frames lost, garbled, swapped or delayed; brown-outs), guided by the firmware's
coverage, judged by the expectation file; each failure shrunk to the fewest faults and
written as a scenario that `hexhil test` replays (docs/fuzzing.md)."""
from __future__ import annotations

import argparse

from hexhil import cli


def table(report) -> str:
    """One row a finding: its failures, the faults it was found with and shrunk to."""
    rows = [("#", "failure", "found at", "faults", "shrunk", "replays")]
    for k, f in enumerate(report.findings, 1):
        rows.append((str(k), "; ".join(f.failures), str(f.found_at), str(len(f.first)),
                     str(len(f.shrunk or f.first)),
                     "-" if f.replayed is None else "yes" if f.replayed else "NO"))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows]
    lines.insert(1, "-" * len(lines[0]))
    return "\n".join(lines)


def _run(args: argparse.Namespace) -> int:
    from hexhil.bus_fuzz import campaign
    from hexhil.cli import emit_json, flush_print

    settings = campaign.Settings(
        expect=args.expect, scenario=args.scenario, window_s=args.window,
        runs=args.runs if args.runs is not None else None if args.time is not None else 200,
        time_s=args.time, seed=args.seed, jobs=args.jobs, scheduler=args.scheduler,
        firmware=args.firmware, main_file=args.in_process,
        kinds=campaign.mutation_kinds(args.kinds.split(",")) if args.kinds
        else campaign.DEFAULT_KINDS, coverage=not args.no_coverage, out=args.out)

    def progress(r: campaign.Report) -> None:
        if not args.quiet:
            flush_print(f"fuzz: {r.executions} executions, {r.rate:.1f}/s, {r.features} "
                        f"features ({r.features - r.baseline_features} new), corpus "
                        f"{r.corpus}, {len(r.findings)} failures")

    report = campaign.fuzz(settings, progress)
    if args.json:
        emit_json(report.as_dict())
        return 1 if report.findings else 0
    print(f"{report.executions} executions in {report.wall_s:.1f} s ({report.rate:.1f}/s; "
          f"shrinking {report.shrink_executions} more), {report.features} features, corpus "
          f"{report.corpus}")
    if not report.findings:
        print("no failure found")
        return 0
    print(table(report))
    for k, f in enumerate(report.findings, 1):
        print(f"\nfinding {k}: " + "; ".join(f.details))
        for m in f.shrunk or f.first:
            print(f"  {m}")
        if f.expect:
            print(f"  replay: {campaign.replay_command(f, settings)}  (trace {f.trace})")
    return 1


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("fuzz", help="fuzz the firmware through its bus: faults in virtual "
                                    "time, shrunk reproducers", description=__doc__)
    p.add_argument("scenario", help="scenario to fuzz, e.g. "
                   "scenarios/flat-tripod.toml")
    p.add_argument("--expect", required=True, metavar="FILE",
                   help="expectation file whose [[expect]] tables judge each execution "
                        "(docs/testing.md); its duration_s is the run's length")
    p.add_argument("--firmware", metavar="PATH",
                   help="fuzz this firmware instead of ours (as hexhil run --firmware: a "
                        "MicroPython main file for the virtual board, an executable, an "
                        "STM32F411 ELF): a fresh run an execution")
    p.add_argument("--in-process", metavar="FILE.py",
                   help="fuzz this Python module's main(board) in this process, as ours "
                        "(the fork server: executions start after boot)")
    p.add_argument("--runs", type=int, metavar="N",
                   help="executions to run (default 200 without --time)")
    p.add_argument("--time", type=float, metavar="S",
                   help="wall seconds to fuzz for (a campaign then depends on the machine)")
    p.add_argument("--window", type=float, default=1.0, metavar="S",
                   help="faults start at or after this virtual time: the state saved after "
                        "boot (default 1)")
    p.add_argument("--seed", type=int, default=0, metavar="N",
                   help="the campaign's seed: the same seed, the same campaign (default 0)")
    p.add_argument("--jobs", type=int, default=1, metavar="N",
                   help="executions at once, in server processes of their own (default 1)")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="run the executions on this Dask distributed scheduler instead")
    p.add_argument("--kinds", metavar="K1,K2",
                   help="fault kinds to draw (default: all the fuzzer knows)")
    p.add_argument("--no-coverage", action="store_true",
                   help="keep no corpus by line coverage (packet sequences still count; "
                        "faster for an ELF, about the same in process)")
    p.add_argument("--out", metavar="DIR",
                   help="write each finding here: its scenario, expectation file and trace")
    p.add_argument("--json", action="store_true", help=cli.JSON_HELP)
    p.add_argument("--quiet", action="store_true", help="no progress line")
    p.set_defaults(func=_run, runs=None)
