"""``hexhil margin SCENARIO --expect FILE``: sweep the servos' Return Delay, the USB-serial
adapter's latency, the bit-error rate and a baud mismatch, in lockstep and in parallel, and
report where the expectations stop holding (table, PNG heat map, first failing setting)."""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys

from hexhil.hil.link.firmware_process import IN_PROCESS, RUNTIMES
from hexhil import cli
from hexhil.cli.run import add_flash_options, flash_files


def _run(args: argparse.Namespace) -> int:

    from hexhil.hil import scenario as scenario_mod
    from hexhil.cli import emit_json
    from hexhil.expect import margin_sweep, spec
    from hexhil.output import check_output, write_failed
    from hexhil.protocol.errors import BadValue, UserError

    if args.jobs < 1:
        raise BadValue("--jobs must be at least 1")
    if args.firmware is not None:
        from hexhil.hil.link.served_firmware import served_firmware

        if args.python is not None:
            raise UserError(f"--firmware {args.firmware} brings its own runtime: leave out "
                            "--runtime")
        served_firmware(args.firmware,   # one line before anything runs
                        flash_files=flash_files(args))
    case = spec.load(args.expect)
    if flash_files(args) is not None:      # a MicroPython ELF's /flash over the case's
        case = dataclasses.replace(case, flash_files=flash_files(args).over(case.flash_files))
    sc = spec.hexapod(args.scenario, scenario_mod.load_scenario(args.scenario))
    if args.png:   # written after the sweep: checked before it
        check_output(args.png, "png")
    case = dataclasses.replace(case, scenario=sc, name=sc.scenario.name or case.name,
                               seed=sc.scenario.seed)
    if args.duration is not None:
        scenario_mod.check_duration(args.duration, "--duration")
        spec.check_windows(args.expect, case.expectations, args.duration,
                           case.scenario.bus.servos)
        case = dataclasses.replace(case, duration_s=args.duration)
    python = args.python or case.python
    m = margin_sweep.sweep(case, python, workers=args.jobs, scheduler=args.scheduler,
                           progress=None if args.quiet else cli.ProgressBar("run"),
                           firmware=args.firmware)
    for axis, points in m.axes.items():
        print(f"\n{axis}")
        for p in sorted(points, key=lambda p: p.settings[0][1]):
            v = p.settings[0][1]
            what = "holds" if p.holds else ("FAILS: " + ", ".join(p.failed)
                                            + (f" ({p.measured[0]})" if p.measured else ""))
            print(f"  {v:>10g}  {p.passed}/{p.total}  {what}")
    rd, lat = m.grid_axes
    print("\nReturn Delay (rows, us) x adapter latency (columns, us): expectations holding")
    print("        " + "".join(f"{v:>8g}" for v in lat))
    for i, r in enumerate(rd):
        row = m.grid[i * len(lat):(i + 1) * len(lat)]
        print(f"{r:>8g}" + "".join(f"{p.passed:>6}/{p.total}" for p in row))
    print("\nfirst failing setting: " + ", ".join(
        f"{k} {'none' if v is None else f'{v:g}'}" for k, v in m.first_failing().items()))
    if args.png:
        try:
            margin_sweep.heat_map(m, args.png, f"{case.name}: expectations of {args.expect} "
                                  f"({case.duration_s:g} s, seed {case.seed})")
        except OSError as exc:   # a full disk: the sweep above is printed, its verdict stands
            sys.stderr.write(f"hexhil: {cli.flag_message(write_failed(args.png, 'png', exc))}\n")
            return 1 if not m.nominal_holds() else 2
        print(f"heat map: {args.png}")
    if args.json:
        emit_json(json.loads(json.dumps(margin_sweep.to_json(m))))
    if not m.nominal_holds():
        sys.stderr.write(f"hexhil: the expectations of {args.expect} fail at nominal timing "
                         "(every setting 0): there is no margin to measure\n")
        return 1
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("margin", help="sweep bus timing (Return Delay, adapter latency, bit "
                                      "errors, baud) until the expectations fail",
                       description=__doc__)
    p.add_argument("scenario", help="scenario file (TOML), e.g. scenarios/flat-tripod.toml")
    p.add_argument("--expect", required=True, metavar="FILE",
                   help="expectation file (docs/testing.md) whose [[expect]] tables must hold")
    p.add_argument("--duration", type=float, metavar="S",
                   help="simulated seconds a run (default: the expectation file's)")
    p.add_argument("--jobs", type=int, default=1, metavar="N", help="worker processes")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="run on this Dask distributed scheduler instead")
    p.add_argument("--runtime", "--python", dest="python", choices=(*RUNTIMES, IN_PROCESS),
                   help=f"firmware runtime (default: the case's); {IN_PROCESS} is faster")
    p.add_argument("--firmware", metavar="PATH",
                   help="your firmware in place of the case's: a MicroPython main file, an "
                        "executable (a C firmware) or an STM32F411 ELF")
    add_flash_options(p)
    p.add_argument("--png", metavar="OUT.png", help="write the heat map")
    p.add_argument("--json", action="store_true", help=cli.JSON_HELP + ": every point of the sweep")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_run)
