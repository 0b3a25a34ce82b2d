"""``hexhil conformance``: check any Dynamixel bus (emulated or real AX-12s, Protocol 1.0; X series,
Protocol 2.0) against the spec (host_tools/dynamixel/conformance/)."""
from __future__ import annotations

import argparse
import math

from hil.scenario import DEFAULT_BAUD
from host_tools.cli import JSON_HELP, emit_json
from protocol.dynamixel import models
from protocol.errors import UserError


def run(args: argparse.Namespace) -> int:
    from host_tools.cli.bus import parse_ids
    from host_tools.dynamixel.conformance import CHECKS
    from host_tools.dynamixel.conformance.report import format_table

    if args.baud <= 0:
        raise UserError(f"--baud must be positive, got {args.baud}")
    if not all(0 < t < math.inf for t in (args.timeout_ms, args.scan_timeout_ms)):
        raise UserError("--timeout-ms and --scan-timeout-ms must be positive and finite")
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
                                   "restore what was changed. Exit 0 only when all pass.")
    p.add_argument("--port", required=True,
                   help="serial port or pyserial URL (/dev/ttyUSB0, /dev/pts/N, socket://127.0.0.1:7000)")
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
