"""``hexhil bus``: serve emulated AX-12A servos in real time on a pty or a TCP port."""
from __future__ import annotations

import argparse
import copy
import sys
from typing import Any

from protocol.errors import UserError

_FAULT_FLAGS = ("unplug", "stall", "overheat", "voltage_sag")


def parse_ids(spec: str) -> list[int]:
    """``1-18`` or ``1,3,5-7`` -> sorted unique servo IDs (0-253)."""
    ids: set[int] = set()
    for part in spec.split(","):
        part = part.strip()
        try:
            if "-" in part:
                lo, hi = (int(x) for x in part.split("-", 1))
            else:
                lo = hi = int(part)
        except ValueError:
            raise UserError(f"--ids {spec!r}: expected IDs like 1-18 or 1,3,5-7") from None
        if not 0 <= lo <= hi <= 253:
            raise UserError(f"--ids {spec!r}: IDs must be 0-253, low before high")
        ids.update(range(lo, hi + 1))
    return sorted(ids)


def build_bus(args: argparse.Namespace, scenario: dict[str, Any], on_fault=None):
    """Servos, clock, faults and bus from flags over scenario over defaults (hil/rig.py)."""
    from hil import rig
    from hil.faults import parse_flag

    sc = copy.deepcopy(scenario) or {"_path": "flags"}
    sb = sc.setdefault("bus", {})
    ids = None
    if args.ids:
        ids = parse_ids(args.ids)
        if args.servos is not None and args.servos != len(ids):
            raise UserError(f"--servos {args.servos} but --ids lists {len(ids)} IDs")
    elif args.servos is not None:
        sb["servos"] = args.servos
    for key in ("edition", "baud"):
        if getattr(args, key) is not None:
            sb[key] = getattr(args, key)
    if args.echo:
        sb["echo"] = True
    sf = sc.setdefault("faults", {})
    if args.bit_error_rate is not None:
        sf["bit_error_rate"] = args.bit_error_rate
    if args.drop_status_rate is not None:
        sf["drop_status_rate"] = args.drop_status_rate
    for kind in _FAULT_FLAGS:
        for spec in getattr(args, kind) or []:
            sf.setdefault(kind, []).append(parse_flag(kind, spec))
    seed = args.seed if args.seed is not None else sc.get("scenario", {}).get("seed", 0)
    built = rig.build(sc, seed, ids=ids, on_fault=on_fault)
    return built.bus, built.faults


def run(args: argparse.Namespace) -> int:
    from hil import serial_server
    from hil import scenario as scenario_mod

    if args.pty and args.tcp is not None:
        raise UserError("choose one transport: --pty or --tcp PORT")
    if args.tcp is not None and not 0 <= args.tcp <= 65535:
        raise UserError(f"--tcp {args.tcp}: port must be 0-65535")
    sc = scenario_mod.load(args.scenario) if args.scenario else {}

    def on_fault(t_us: int, name: str, detail: str) -> None:
        if args.verbose:
            sys.stderr.write(f"fault t={t_us / 1e6:.6f}s {name}: {detail}\n")

    bus, faults = build_bus(args, sc, on_fault)
    server = serial_server.RealTimeServer(bus)
    serial_server.install_sigterm()
    try:
        if args.tcp is None:
            server.serve_pty(serial_server.flush_print)
        else:
            try:
                server.serve_tcp(args.tcp, args.host, serial_server.flush_print)
            except OSError as exc:
                raise UserError(str(exc)) from None
    except (KeyboardInterrupt, serial_server.Stop):
        pass
    st = bus.stats
    counts = ", ".join(f"{k} {v}" for k, v in sorted(faults.counts.items())) or "none"
    serial_server.flush_print(
        f"served {st['packets']} packets, {st['replies']} replies, {st['collisions']} collisions, "
        f"{st['bad_checksum']} bad checksums; faults: {counts}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bus", help="serve emulated AX-12 servos on a pty or TCP port",
                       description="Serve emulated AX-12A servos in real time (wire time and "
                                   "return delay honoured) for stock Protocol 1.0 clients.")
    p.add_argument("--servos", type=int, default=None, help="number of servos (default 18)")
    p.add_argument("--ids", default=None, help="servo IDs, e.g. 1-18 or 1,3,5-7")
    p.add_argument("--pty", action="store_true", help="serve on a pseudo-terminal, the default (prints 'pty: PATH')")
    p.add_argument("--tcp", type=int, default=None, metavar="PORT", help="serve on a TCP port")
    p.add_argument("--host", default="127.0.0.1", help="address for --tcp (default 127.0.0.1)")
    p.add_argument("--baud", type=int, default=None, help="line rate in bit/s (default 1000000)")
    p.add_argument("--echo", action="store_true", help="echo the master's bytes (single-wire adapter)")
    p.add_argument("--scenario", default=None, help="scenario TOML ([bus], [faults], [scenario].seed)")
    p.add_argument("--edition", choices=("emanual", "original"), default=None,
                   help="control-table defaults of this manual edition (default emanual)")
    p.add_argument("--seed", type=int, default=None, help="fault RNG seed (default: scenario's, else 0)")
    p.add_argument("--bit-error-rate", type=float, default=None, metavar="P",
                   help="probability each data bit on the line flips")
    p.add_argument("--drop-status-rate", type=float, default=None, metavar="P",
                   help="probability a status packet is lost")
    p.add_argument("--unplug", action="append", metavar="ID:AT_S[:UNTIL_S]",
                   help="servo silent from AT_S (seconds after start) to UNTIL_S; repeatable")
    p.add_argument("--stall", action="append", metavar="ID:AT_S[:UNTIL_S]",
                   help="an external load blocks the horn (overload alarm); repeatable")
    p.add_argument("--overheat", action="append", metavar="ID:TEMP_C:AT_S[:UNTIL_S]",
                   help="servo heats towards TEMP_C; repeatable")
    p.add_argument("--voltage-sag", dest="voltage_sag", action="append",
                   metavar="VOLTS:AT_S[:UNTIL_S]", help="supply of every servo drops; repeatable")
    p.add_argument("-v", "--verbose", action="store_true", help="print each injected fault on stderr")
    p.set_defaults(func=run)
