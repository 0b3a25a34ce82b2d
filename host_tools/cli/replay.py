"""``hexhil replay FILE``: replay a trace into the firmware, or onto a CAN bus with --can."""
from __future__ import annotations

import argparse
import sys

from hexhil import replay
from hexhil.cli import JSON_HELP, emit, emit_json
from hexhil.cli.run import add_flash_options, flash_files


def run(args: argparse.Namespace) -> int:
    if args.can:
        r = replay.replay_can(args.file, args.can, rate=1.0 if args.rate is None else args.rate,
                              start_s=args.start, end_s=args.end, bus_args=args.can_arg)
        emit(args, r, f"sent {r['frames']} frames to {r['target']} in {r['wall_s']:.3f} s "
                      f"(trace span {r['span_s']:.3f} s)")
        return 0
    r = replay.replay_firmware(args.file, python=args.python,
                               rate=0.0 if args.rate is None else args.rate,
                               start_s=args.start, end_s=args.end, topics=args.topics,
                               firmware=args.firmware, scenario=args.scenario,
                               flash_files=flash_files(args))
    d = r.divergence
    if args.json:
        emit_json(r.as_dict())
    elif d is None and r.extra.get("log"):
        print(f"identical: {r.extra['master_packets']} logged master packets and "
              f"{r.extra['controller_frames']} controller CAN frames, as the firmware sent them")
    elif d is None:
        print(f"identical: {r.exchanges} link exchanges, {r.compared_messages} firmware "
              f"messages compared")
    else:
        where = (f"{'packet' if d.topic == 'uart' else 'frame'} {d.exchange}"
                 if r.extra.get("log") else f"exchange {d.exchange}")
        print(f"DIVERGED at t={d.t_s:.6f} s ({where}) on {d.topic}:\n"
              f"  expected {d.expected}\n  actual   {d.actual}")
        if d.packets is not None:
            print(f"  expected packets: {'; '.join(d.packets['expected']) or '(none)'}\n"
                  f"  actual packets:   {'; '.join(d.packets['actual']) or '(none)'}")
    if d is not None and r.stderr_tail.strip():
        sys.stderr.write(r.stderr_tail.strip().splitlines()[-1] + "\n")
    return 0 if d is None else 1


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("replay", help="replay a trace into the firmware or onto a CAN bus",
                       description="Exit 0: the firmware's outputs are identical to the "
                                   "trace's; 1: they diverge (first divergence reported).")
    p.add_argument("file", help="an MCAP trace recorded with --out")
    add_flash_options(p)
    p.add_argument("--firmware", metavar="PATH", help="the firmware the trace was recorded "
                   "with (hexhil run --firmware: a MicroPython main file or an executable)")
    p.add_argument("--scenario", metavar="SCENARIO", default=None,
                   help="for a robot's imported log: the scenario whose firmware settings the "
                        "firmware gets (default: the log's servo line, the rest defaults)")
    p.add_argument("--runtime", "--python", dest="python", choices=("micropython", "cpython"),
                   default="micropython", help="runtime for the firmware (default micropython)")
    p.add_argument("--rate", type=float, default=None,
                   help="wall-clock pacing, 1 = real time (default: as fast as possible "
                        "into the firmware, real time onto CAN); 0 = no pacing")
    p.add_argument("--start", type=float, metavar="S", help="compare from this time (s)")
    p.add_argument("--end", type=float, metavar="S", help="stop at this time (s)")
    p.add_argument("--topics", action="append", metavar="T[,T...]",
                   help=f"compare only these firmware outputs: {', '.join(replay.TOPICS)}")
    p.add_argument("--can", metavar="INTERFACE:CHANNEL",
                   help="send the logged CAN frames through python-can instead")
    p.add_argument("--can-arg", action="append", default=[], metavar="KEY=VALUE",
                   help="extra python-can bus argument (e.g. host=127.0.0.1, port=29536)")
    p.add_argument("--json", action="store_true", help=JSON_HELP)
    p.set_defaults(func=run)
