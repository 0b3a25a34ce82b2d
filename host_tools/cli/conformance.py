"""``hexhil conformance``: check any Dynamixel bus (emulated or real AX-12s, Protocol 1.0; X series,
Protocol 2.0) against the spec (host_tools/dynamixel/conformance/)."""
from __future__ import annotations

import argparse
import math

from hexhil.hil.scenario import DEFAULT_BAUD
from hexhil.cli import JSON_HELP, emit_json
from hexhil.protocol.dynamixel import models
from hexhil.protocol.errors import BadValue, UserError


def _capture(args: argparse.Namespace) -> int:
    """``--capture FILE``: the master check on a captured line (the same counts as a run's)."""
    from hexhil.cli.bus import parse_ids
    from hexhil.dynamixel.conformance.capture import check_capture

    r = check_capture(args.capture, args.model, parse_ids(args.ids) if args.ids else None,
                      args.map)
    v, ln = r["violations"], r["line"]
    wrong = ", ".join(f"{k} {n}" for k, n in v["counts"].items() if n) or "none"
    print(f"{r['capture']}: {r['master_bursts']} master bursts at {r['baud']} bit/s, Protocol "
          f"{r['protocol']}.0 ({r['model']}), servos {','.join(map(str, r['servos']))}")
    for e in v["events"]:
        print(f"  {e['t_s']:.6f} s {e['kind']}: {e['packet']} ({e['detail']})")
    delays = "; ".join(f"id {i} " + (f"{d['min']}-{d['max']}" if d["min"] != d["max"]
                                     else str(d["min"])) + " us"
                       for i, d in ln["return_delay_us"].items())
    print(f"line: {ln['framing_errors']} framing errors, {ln['unanswered']} pings and reads "
          f"unanswered; return delays: {delays or 'none measured'}")
    print(f"master violations: {wrong}", flush=True)
    if args.json:
        emit_json(r)
    return 0 if r["ok"] else 1


def run(args: argparse.Namespace) -> int:
    from hexhil.cli.bus import parse_ids

    if (args.port is None) == (args.capture is None):
        raise UserError("give --port PORT (check a live bus) or --capture FILE (check a "
                        "captured master), one of them")
    if args.capture is not None:
        return _capture(args)
    from hexhil.dynamixel.conformance import CHECKS
    from hexhil.dynamixel.conformance.report import format_table

    if args.baud <= 0:
        raise BadValue(f"--baud must be positive, got {args.baud}")
    if not all(0 < t < math.inf for t in (args.timeout_ms, args.scan_timeout_ms)):
        raise BadValue("--timeout-ms and --scan-timeout-ms must be positive and finite")
    ids = parse_ids(args.ids) if args.ids else None
    protocol = models.protocol(args.model) if args.model else args.protocol
    result = CHECKS[protocol](args.port, args.baud, ids, args.timeout_ms / 1000.0,
                        args.scan_timeout_ms / 1000.0)
    print(format_table(result), flush=True)
    if args.json:
        emit_json(result)
    return 0 if result["ok"] else 1


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("conformance", help="check any Dynamixel bus (Protocol 1.0 or 2.0) against the spec",
                       description="Scan, ping, read the control table and check error replies, "
                                   "status return levels and response timing of every servo; "
                                   "restore what was changed. Exit 0 only when all pass. "
                                   "With --capture, check a captured master instead.")
    p.add_argument("--port", default=None,
                   help="serial port or pyserial URL (/dev/ttyUSB0, /dev/pts/N, socket://127.0.0.1:7000)")
    p.add_argument("--capture", default=None, metavar="FILE",
                   help="instead of a port: run the master check on a captured line, a sigrok "
                        "capture (.sr) or a trace's /serial (.mcap); exit 1 on a violation")
    p.add_argument("--map", default=None, metavar="MAP.toml",
                   help="with --capture: the capture's [serial] channels, baud, protocol")
    p.add_argument("--baud", type=int, default=DEFAULT_BAUD, help="bit/s (default 1000000)")
    p.add_argument("--ids", default=None, help="IDs to check, e.g. 1-18 (default: scan 0-253)")
    p.add_argument("--timeout-ms", type=float, default=50.0,
                   help="status packet timeout (default 50; USB adapters need > latency timer)")
    p.add_argument("--scan-timeout-ms", type=float, default=15.0,
                   help="per-ID PING timeout while scanning 0-253 (default 15)")
    p.add_argument("--protocol", type=int, choices=(1, 2), default=1,
                   help="Dynamixel protocol: 1 (AX-12, the default) or 2 (X series: CRC, "
                        "stuffing, sync/bulk/fast reads, EEPROM lock)")
    p.add_argument("--model", choices=tuple(models.MODELS), default=None,
                   help="the servos' model: checks in its protocol (instead of --protocol); "
                        "each servo is checked against the table of the model it says it is")
    p.add_argument("--json", action="store_true", help=JSON_HELP)
    p.set_defaults(func=run)
