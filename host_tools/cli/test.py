"""``hexhil test FILE...``: run expectation files (docs/testing.md) against our firmware (or
yours, ``--firmware``; or check a run recorded on a real board, ``--trace``) and say pass
or fail: a table, exit 0 (all pass), 1 (an expectation failed), 2 (bad input),
JUnit XML for CI, and the trace of each failing case kept with its failures in it."""
from __future__ import annotations

import argparse
import sys
from typing import Sequence

from hexhil.hil.link.firmware_process import IN_PROCESS, RUNTIMES
from hexhil import cli
from hexhil.cli.run import add_flash_options, add_masked_limit, flash_files


def table(results: Sequence) -> str:
    """One row an expectation: case, expectation, measured value, limit, PASS/FAIL."""
    rows = [("case", "expectation", "measured", "limit", "result")]
    for r in results:
        for o in r.outcomes:
            rows.append((r.label, o.name, o.measured, o.limit, "pass" if o.passed else "FAIL"))
    widths = [max(len(row[i]) for row in rows) for i in range(4)]
    lines = ["  ".join(c.ljust(w) for c, w in zip(row[:4], widths)) + "  " + row[4]
             for row in rows]
    lines.insert(1, "-" * len(lines[0]))
    return "\n".join(lines)


def _run(args: argparse.Namespace) -> int:
    from hexhil.expect import case_runs, junit, spec
    from hexhil.output import check_output
    from hexhil.protocol.errors import BadFile, BadValue, UserError

    if args.jobs < 1 or args.repeat < 1:
        raise BadValue("--jobs and --repeat must be at least 1")
    if args.firmware is not None and args.python is not None:
        raise UserError(f"--firmware {args.firmware} brings its own runtime: leave out --runtime")
    if args.in_process is not None:
        from hexhil.in_process import load_main

        if args.firmware is not None or args.python not in (None, IN_PROCESS):
            raise UserError(f"--in-process {args.in_process} runs in this process: leave out "
                            "--firmware and --runtime")
        load_main(args.in_process)   # one line before anything runs
    if args.firmware is not None and args.no_tactile:
        raise UserError("--no-tactile sets our firmware's obstacle rule: a firmware of yours "
                        f"({args.firmware}) reads no such setting")
    if args.trace is not None and (len(args.files) != 1 or args.firmware or args.python
                                   or args.no_tactile or args.repeat != 1 or args.in_process):
        raise UserError("--trace evaluates one recorded run: give one FILE, and no --firmware, "
                        "--runtime, --no-tactile or --repeat")
    if args.firmware is not None:
        from hexhil.hil.link.served_firmware import served_firmware
        from hexhil.hil.run.limits import MASKED_LIMIT_S

        served_firmware(args.firmware, coverage=args.coverage,   # one line before anything runs
                        flash_files=flash_files(args),
                        masked_limit_s=MASKED_LIMIT_S if args.masked_limit is None
                        else args.masked_limit)
    elif args.coverage is not None:
        raise UserError("--coverage needs an STM32F411 ELF given as --firmware")
    if args.coverage_libraries and args.coverage is None:
        raise UserError("--coverage-libraries needs --coverage (the LCOV file to write)")
    for flag in ("junit", "coverage"):   # written after every case ran: checked first
        if getattr(args, flag) is not None:
            check_output(getattr(args, flag), flag)
    cli.show_console(args.quiet)
    cases = [spec.load(f) for f in args.files]
    names = [c.name for c in cases]
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise UserError(f"two files name the case {dup!r}: give one a [case] name")
    if args.trace is not None:
        results = [case_runs.evaluate_recorded(cases[0], args.trace, args.keep_traces,
                                               args.overwrite)]
    else:
        jobs = case_runs.jobs_for(cases, args.repeat,
                                  tactile=False if args.no_tactile else None,
                                  python=args.python, firmware=args.firmware,
                                  flash_files=flash_files(args), main_file=args.in_process,
                                  keep_dir=args.keep_traces, overwrite=args.overwrite,
                                  limits=cli.limits(args), masked_limit_s=args.masked_limit)
        if args.keep_traces and not args.overwrite:   # refused before anything runs
            for job in jobs:
                kept = case_runs.kept_path(args.keep_traces, job.label)
                if kept.exists():
                    raise BadFile(f"--keep-traces: {kept} exists: pass --overwrite to "
                                  "replace it")
        bar = None if args.quiet or len(jobs) < 2 else cli.ProgressBar("run")
        if args.coverage is None:
            results = case_runs.run_all(jobs, args.jobs, args.scheduler, progress=bar)
        else:
            results = _covered(jobs, args, bar)
    print(table(results))
    failed = [r for r in results if not r.passed]
    n = sum(len(r.outcomes) for r in results)
    bad = sum(not o.passed for r in results for o in r.outcomes)
    print(f"{n - bad} of {n} expectations passed in {len(results)} runs"
          + (f"; {bad} failed" if bad else ""))
    for r in results:
        ending = r.summary.get("ending") or {}
        if ending.get("kind", "completed") != "completed":
            print(f"{r.label}: {ending['reason']}"
                  + "".join(f"\n  {x}" for x in ending.get("last_lines", ())))
    for r in failed:
        if r.trace:
            print(f"trace of {r.label} (failures on /expectations): {r.trace}")
    if args.json:
        cli.emit_json(as_json(results))
    if args.junit:
        try:
            junit.write(results, args.junit)
        except UserError as exc:   # the verdict stands: 1 if a case failed
            sys.stderr.write(f"hexhil: {exc}\n")
            return 1 if failed else 2
    return 1 if failed else 0


def as_json(results: Sequence) -> dict:
    """``--json``: each case's verdicts, ending and console's last lines."""
    return {"passed": all(r.passed for r in results),
            "cases": [{"label": r.label, "seed": r.seed, "passed": r.passed,
                       "ending": r.summary.get("ending"),
                       "console": r.summary.get("console", []),
                       "serial_digest": r.summary.get("serial_digest"), "trace": r.trace,
                       "expectations": [{"name": o.name, "kind": o.kind,
                                         "measured": o.measured, "limit": o.limit,
                                         "passed": o.passed} for o in r.outcomes]}
                      for r in results]}


def _covered(jobs: list, args: argparse.Namespace, bar: object) -> list:
    """Run the cases, each with an ELF's line coverage of its own, merged into one file."""
    import dataclasses
    import tempfile
    from pathlib import Path

    from hexhil.hil.mcu.coverage import merge
    from hexhil.expect import case_runs

    with tempfile.TemporaryDirectory(prefix="hexhil-cov-") as tmp:
        jobs = [dataclasses.replace(j, coverage=str(Path(tmp) / f"{k}.info"),
                                    coverage_libraries=args.coverage_libraries)
                for k, j in enumerate(jobs)]
        results = case_runs.run_all(jobs, args.jobs, args.scheduler, progress=bar)
        infos = [Path(j.coverage).read_text() for j in jobs if Path(j.coverage).exists()]
    Path(args.coverage).write_text(merge(infos))
    print(f"coverage of {len(infos)} runs: {args.coverage}")
    return results


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("test", help="run expectation files against the firmware: pass/fail, "
                                    "JUnit XML", description=__doc__)
    p.add_argument("files", nargs="+", metavar="FILE",
                   help="expectation file (TOML, docs/testing.md), e.g. tests/firmware/*.toml")
    p.add_argument("--junit", metavar="OUT.xml", help="write the results as JUnit XML")
    p.add_argument("--jobs", type=int, default=1, metavar="N",
                   help="cases run at once in worker processes (default 1)")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="run the cases on this Dask distributed scheduler instead")
    p.add_argument("--repeat", type=int, default=1, metavar="N",
                   help="run each case N times, repeat k with the case's seed + k")
    p.add_argument("--keep-traces", metavar="DIR",
                   help="keep the MCAP trace of every failing case here, its failed "
                        "expectations on /expectations at the moment each failed")
    p.add_argument("--overwrite", action="store_true",
                   help="replace a kept trace of the same name in --keep-traces DIR (without "
                        "it, an existing one is refused before anything runs)")
    p.add_argument("--runtime", "--python", dest="python", choices=(*RUNTIMES, IN_PROCESS),
                   help="firmware runtime for every case (default: each case's, else "
                        f"micropython); {IN_PROCESS} is faster with the same digest")
    p.add_argument("--coverage", metavar="FILE.info", help="with an ELF --firmware: its LCOV "
                   "line coverage over every case, merged (docs/elf-firmware.md)")
    p.add_argument("--coverage-libraries", action="store_true", help="--coverage counts the "
                   "toolchain's libraries too (newlib, libgcc), not only the firmware's own "
                   "sources")
    p.add_argument("--firmware", metavar="PATH",
                   help="run every case with this firmware instead of ours (as hexhil run "
                        "--firmware: a MicroPython main file for the virtual board, or an "
                        "executable such as a C firmware); a case may name one itself "
                        "([case] firmware)")
    add_flash_options(p)
    add_masked_limit(p)
    p.add_argument("--in-process", metavar="FILE.py",
                   help="run every case with this Python module's main(board) in this "
                        "process, as ours (a variant of our firmware, e.g. a reproducer of "
                        "hexhil fuzz --in-process)")
    p.add_argument("--trace", metavar="RUN.mcap",
                   help="run nothing: check one FILE's expectations on this recorded run, "
                        "e.g. a real board's (hexhil bus --world SCENARIO --port DEVICE --out "
                        "RUN.mcap)")
    p.add_argument("--no-tactile", action="store_true",
                   help="run every case with the Eq. 5-7 obstacle rule off, as "
                        "'hexhil run --no-tactile' (the tactile expectations should fail)")
    p.add_argument("--json", action="store_true", help=cli.JSON_HELP + ": each case's "
                   "expectations, ending and console's last lines")
    p.add_argument("--quiet", action="store_true", help="no progress bar, and do not show "
                   "the firmware's console on stderr as it runs (with --jobs 1)")
    cli.add_limits(p)
    p.set_defaults(func=_run)
