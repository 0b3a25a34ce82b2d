"""``hexhil trace info|cat|export|recover|import|import-csv``: look inside MCAP traces, and
make them of a robot's logs."""
from __future__ import annotations

import argparse
import json
import sys

from hexhil.cli import JSON_HELP, OVERWRITE_HELP, actions, emit, emit_json
from hexhil.trace import export, import_csv, import_logs, reader, recover
from hexhil.trace.import_csv import CSV_OPTIONAL, CSV_POSE, CSV_REQUIRED
from hexhil.protocol.errors import BadValue


def _filters(p: argparse.ArgumentParser) -> None:
    p.add_argument("--topics", action="append", metavar="T[,T...]",
                   help="only these topics (exact or glob such as '/can/*'; repeatable)")
    p.add_argument("--start", type=float, metavar="S", help="from this log time in s")
    p.add_argument("--end", type=float, metavar="S", help="up to (not including) this time")


def _info(args: argparse.Namespace) -> int:
    s = reader.info(args.file)
    if args.json:
        emit_json(s)
        return 0
    print(f"file:      {s['file']}")
    print(f"library:   {s['library']}")
    print(f"messages:  {s['messages']} in {s['chunks']} chunks ({', '.join(s['compression'])})")
    print(f"start:     {s['start_s']:.6f} s")
    print(f"end:       {s['end_s']:.6f} s")
    print(f"duration:  {s['duration_s']:.6f} s")
    for k, v in sorted(s["metadata"].items()):
        print(f"meta:      {k} = {v}")
    width = max((len(t["topic"]) for t in s["topics"]), default=5)
    print("topics:")
    for t in s["topics"]:
        print(f"  {t['topic']:<{width}}  {t['messages']:>9}  {t['schema']} "
              f"({t['schema_encoding'] or t['message_encoding']})")
    return 0


def _cat(args: argparse.Namespace) -> int:
    if args.limit < 0:
        raise BadValue(f"--limit must be 0 (no limit) or more, got {args.limit}")
    n = 0
    out = sys.stdout
    with reader.open_trace(args.file) as tr:
        for m, value in tr.decoded(args.topics, args.start, args.end):
            out.write(f"{m.log_time_ns / 1e9:.6f} {m.topic} "
                      f"{json.dumps(value, sort_keys=True)}\n")
            n += 1
            if args.limit and n >= args.limit:
                break
    if args.json:
        emit_json({"messages": n})
    return 0


def _export(args: argparse.Namespace) -> int:
    r = export.export(args.file, args.out, args.topics, args.start, args.end)
    emit(args, r, f"exported {r['messages']} messages to {', '.join(r['files'])}")
    return 0


def _recover(args: argparse.Namespace) -> int:
    r = recover.recover(args.file, args.out, args.overwrite)
    skipped = "".join(f"; skipped {d['bytes']} damaged bytes at byte {d['byte']} "
                      f"({d['after_s']:.6f} s .. {d['before_s']:.6f} s)"
                      for d in r["damaged"] if d["why"] == "damaged" and d["before_s"] is not None)
    orphans = f"; {r['orphaned_messages']} messages lost their channel record" \
        if r["orphaned_messages"] else ""
    emit(args, r, f"recovered {r['messages']} messages ({r['start_s']:.6f} s .. {r['end_s']:.6f} s) "
                  f"into {r['output']}; stopped at: {r['stopped']}{skipped}{orphans}")
    return 0


def _import_csv(args: argparse.Namespace) -> int:
    r = import_csv.import_csv(args.csv, args.out, overwrite=args.overwrite)
    emit(args, r, f"imported {r['samples']} samples ({'with' if r['pose'] else 'without'} pose) "
                  f"into {r['output']}")
    return 0


def _import(args: argparse.Namespace) -> int:
    r = import_logs.import_log(args.file, args.out, args.kind, args.map, args.overwrite)
    what = {"can": lambda s: f"{s['frames']} CAN frames ({s['firmware_frames']} the firmware's)",
            "serial": lambda s: f"{s['bursts']} serial bursts ({s['master_bursts']} the "
                                f"master's) at {s['baud']} bit/s, Protocol {s['protocol']}.0",
            "rosbag2": lambda s: f"{s['messages']} messages of {len(s['topics'])} topics"}
    said = "; ".join(what[s["kind"]](s) for s in r["logs"])
    emit(args, r, f"imported {said} into {r['output']}")
    return 0


_TRACE_HELP = "an MCAP trace (hexhil run/bus/beams run --out, or trace import-csv)"


def register(sub: argparse._SubParsersAction) -> None:
    tsub = actions(sub, "trace", "inspect, export, recover and import MCAP traces")

    q = tsub.add_parser("info", help="topics, schemas, counts, start, end, duration")
    q.add_argument("file", help=_TRACE_HELP)
    q.add_argument("--json", action="store_true", help=JSON_HELP)
    q.set_defaults(func=_info)

    q = tsub.add_parser("cat", help="print messages, one per line: time_s topic json")
    q.add_argument("file", help=_TRACE_HELP)
    _filters(q)
    q.add_argument("--limit", type=int, default=0, help="stop after N messages")
    q.add_argument("--json", action="store_true", help=JSON_HELP + ": the message count")
    q.set_defaults(func=_cat)

    q = tsub.add_parser("export", help="CSV per topic, or CAN to .asc/.blf/.log/.trc")
    q.add_argument("file", help=_TRACE_HELP)
    q.add_argument("out", help="OUT.csv (one topic), a directory (one CSV per topic), "
                               "or OUT.asc/.blf/.log/.trc (the /can/raw frames)")
    _filters(q)
    q.add_argument("--json", action="store_true", help=JSON_HELP)
    q.set_defaults(func=_export)

    q = tsub.add_parser("recover", help="salvage an unfinished/crashed MCAP into a valid one")
    q.add_argument("file", help="the unfinished or damaged MCAP (a run killed mid-write)")
    q.add_argument("out", help="the valid MCAP to write (not the input file)")
    q.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    q.add_argument("--json", action="store_true", help=JSON_HELP)
    q.set_defaults(func=_recover)

    q = tsub.add_parser("import", help="a robot's CAN log, servo-line capture or rosbag2 -> MCAP",
                        description="A robot's own log as a trace on the virtual clock: a CAN "
                                    "log python-can reads (.asc .blf .log .csv .trc .mf4 .db), "
                                    "a sigrok capture of the servo line (.sr, decoded as "
                                    "Dynamixel traffic) or a rosbag2 folder (topics mapped by "
                                    "--map). docs/traces.md, \"Your robot's logs\".")
    q.add_argument("file", nargs="+", help="the log: FILE.asc/.blf/.log..., CAPTURE.sr, or a "
                                           "rosbag2 folder; one of each kind of one session")
    q.add_argument("--as", dest="kind", choices=[k.value for k in import_logs.LogKind],
                   default=None, help="what the file is (default: from its name)")
    q.add_argument("--map", default=None, metavar="MAP.toml",
                   help="[serial] channels/baud/protocol, [can] tx_ids, [topics.\"/t\"] as = "
                        "joints|switches|can")
    q.add_argument("--out", required=True, metavar="T.mcap", help="the MCAP trace to write")
    q.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    q.add_argument("--json", action="store_true", help=JSON_HELP)
    q.set_defaults(func=_import)

    q = tsub.add_parser("import-csv", help="a robot's force+pose CSV -> MCAP for 'estimate'",
                        description="A physical robot's force log as a trace 'hexhil estimate' "
                                    f"reads. The CSV needs a header with {', '.join(CSV_REQUIRED)} "
                                    f"(s, N); with {', '.join(CSV_POSE)} (m, rad) the body pose "
                                    f"too; {', '.join(CSV_OPTIONAL)} are read if there; other "
                                    "columns are ignored.")
    q.add_argument("csv", help="the robot's CSV log (columns above)")
    q.add_argument("out", help="the MCAP trace to write")
    q.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    q.add_argument("--json", action="store_true", help=JSON_HELP)
    q.set_defaults(func=_import_csv)
