"""``hexhil bus``: serve emulated Dynamixel servos of any model in protocol/dynamixel/models.py
(AX-12A: Protocol 1.0; XL430-W250-T, XM430-W350-T: Protocol 2.0) in real time on a pty or a
TCP port."""
from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from hexhil.hil.canbus.socketcand import DEFAULT_PORT
from hexhil.hil.scenario import DEFAULT_BAUD, FaultEntry, FaultKind, Scenario, check_seed
from hexhil.hil.scenario import parse as parse_scenario
from hexhil.hil.scenario.sections import SENSOR_NODE_PROTOCOL
from hexhil.cli import JSON_HELP, OVERWRITE_HELP, flush_print
from hexhil.protocol import sensor_node
from hexhil.protocol.dynamixel import models
from hexhil.protocol.errors import BadValue, UserError

_FAULT_FLAGS = ("unplug", "stall", "overheat", "voltage_sag")
# A reply due while the world catches up leaves that much late. A master waits past a
# reply's wire time and Return Delay: our firmware 10 ms (firmware/hal/serial.py LATENCY_US,
# a pty or USB adapter's slack), the dynamixel-sdk 2 x LATENCY_TIMER + 2 ms = 34 ms
# (port_handler.setPacketTimeout). Half the tighter one leaves the other half to the pty and
# the master's own scheduling; a lag below it cannot cost a master a reply.
MASTER_LAG_LIMIT_MS = 5.0


def lag_warning(pacing: dict[str, Any]) -> str | None:
    """The warning a real-time world's pacing deserves, or None when no master can notice."""
    if pacing["max_lag_ms"] <= MASTER_LAG_LIMIT_MS:
        return None
    return (f"warning: the simulation fell up to {pacing['max_lag_ms']:.1f} ms behind the wall "
            f"clock (over {MASTER_LAG_LIMIT_MS:g} ms): replies that late can time out a master "
            f"(our firmware waits 10 ms, the dynamixel-sdk 34 ms); the machine is overloaded")


def parse_injection(line: str) -> tuple[str, dict[str, Any]]:
    """``KIND key=value ...`` (a ``--inject-stdin`` line) -> the kind and its parameters;
    values are JSON (3, 0.5, true) or else strings."""
    words = line.split()
    if not words:
        raise BadValue("empty fault line: expected KIND key=value ..., e.g. brownout id=3")
    params: dict[str, Any] = {}
    for word in words[1:]:
        key, eq, text = word.partition("=")
        if not eq or not key:
            raise BadValue(f"{line.strip()!r}: expected key=value, got {word!r}")
        try:
            params[key] = json.loads(text)
        except ValueError:
            params[key] = text
    return words[0], params


def _read_injections(rt: Any) -> None:
    """Each stdin line a fault for ``rt`` (a thread: serving goes on meanwhile)."""
    def complain(message: str) -> None:
        sys.stderr.write(f"hexhil: {message}\n")

    for line in sys.stdin:
        if not line.strip():
            continue
        try:
            kind, params = parse_injection(line)
        except UserError as exc:
            complain(str(exc))
            continue
        rt.inject(kind, on_error=complain, **params)


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
            raise BadValue(f"--ids {spec!r}: expected IDs like 1-18 or 1,3,5-7") from None
        if not 0 <= lo <= hi <= 253:
            raise BadValue(f"--ids {spec!r}: IDs must be 0-253, low before high")
        ids.update(range(lo, hi + 1))
    return sorted(ids)


def parse_flag(kind: str, spec: str) -> dict[str, Any]:
    """A ``hexhil bus`` fault flag as a [faults] entry, as a scenario file writes it.

    ``--unplug ID:AT_S[:UNTIL_S]``, ``--stall ID:AT_S[:UNTIL_S]``,
    ``--overheat ID:TEMP_C:AT_S[:UNTIL_S]``, ``--voltage-sag VOLTS:AT_S[:UNTIL_S]``.
    """
    parts = spec.split(":")
    head = 2 if kind in ("overheat",) else 1
    try:
        nums = [float(p) for p in parts]
    except ValueError:
        raise BadValue(f"--{kind.replace('_', '-')} {spec!r}: expected numbers separated by ':'") from None
    if not head + 1 <= len(nums) <= head + 2:
        raise BadValue(f"--{kind.replace('_', '-')} {spec!r}: see 'hexhil bus --help' for the form")
    out: dict[str, Any] = {"at_s": nums[head]}
    if len(nums) == head + 2:
        out["until_s"] = nums[head + 1]
    if kind == "voltage_sag":
        out["volts"] = nums[0]
    else:
        if nums[0] != int(nums[0]):
            raise BadValue(f"--{kind} {spec!r}: servo id must be an integer")
        out["id"] = int(nums[0])
        if kind == "overheat":
            out["temperature_c"] = nums[1]
    FaultEntry.parse(FaultKind(kind), out, f"--{kind.replace('_', '-')}")   # its rules
    return out


def scenario_from_flags(args: argparse.Namespace, scenario: Scenario | None
                        ) -> tuple[Scenario, int, list[int] | None]:
    """Flags over scenario over defaults: the scenario to build, its seed and the servo IDs."""
    ids = None
    bus: dict[str, Any] = {}
    if args.ids:
        ids = parse_ids(args.ids)
        if args.servos is not None and args.servos != len(ids):
            raise UserError(f"--servos {args.servos} but --ids lists {len(ids)} IDs")
    elif args.servos is not None:
        bus["servos"] = args.servos
    for key in ("edition", "baud", "model"):
        if getattr(args, key) is not None:
            bus[key] = getattr(args, key)
    if args.echo:
        bus["echo"] = True
    faults: dict[str, Any] = {}
    if args.bit_error_rate is not None:
        faults["bit_error_rate"] = args.bit_error_rate
    if args.drop_status_rate is not None:
        faults["drop_status_rate"] = args.drop_status_rate
    for kind in _FAULT_FLAGS:
        for spec in getattr(args, kind) or []:
            faults.setdefault(kind, []).append(parse_flag(kind, spec))
    base = scenario if scenario is not None else parse_scenario({}, "flags")
    sc = base.overlay({"bus": bus, "faults": faults})
    seed = check_seed(args.seed, "--seed") if args.seed is not None else sc.scenario.seed
    return sc, seed, ids


def build_bus(args: argparse.Namespace, scenario: Scenario | None, on_fault=None):
    """Servos, clock, faults and bus from flags over scenario over defaults (hil/run/rig.py)."""
    from hexhil.hil.run import rig

    sc, seed, ids = scenario_from_flags(args, scenario)
    built = rig.build(sc, seed, ids=ids, on_fault=on_fault)
    return built.bus, built.faults


def _sensor_id(args: argparse.Namespace, sc: Scenario) -> int | None:
    """The sensor node's ID, or None: on with --world unless --no-sensor-node or
    ``[bus] sensor_node = false``; ``--sensor-id``/``sensor_node_id`` move it."""
    bus = sc.bus
    on = bus.sensor_node if bus.sensor_node is not None else args.world is not None
    if args.no_sensor_node or models.protocol(bus.model) != SENSOR_NODE_PROTOCOL or not on:
        return None
    if args.sensor_id is not None:
        if not 0 <= args.sensor_id <= 253:
            raise BadValue(f"--sensor-id {args.sensor_id}: must be 0-253")
        return args.sensor_id
    return bus.sensor_node_id if bus.sensor_node_id is not None else sensor_node.DEFAULT_ID


def run(args: argparse.Namespace) -> int:
    from hexhil.hil.servobus import serial_server
    from hexhil.hil import scenario as scenario_mod
    from hexhil import cli
    from hexhil.realtime_run import Pty, RealTimeRun, Rfc2217, SerialPort, Tcp

    if sum((args.pty, args.tcp is not None, args.rfc2217 is not None, args.port is not None)) > 1:
        raise UserError("choose one transport: --pty, --tcp PORT, --rfc2217 PORT or --port DEVICE")
    for flag in ("tcp", "rfc2217"):
        if getattr(args, flag) is not None and not 0 <= getattr(args, flag) <= 65535:
            raise BadValue(f"--{flag} {getattr(args, flag)}: port must be 0-65535")
    if args.rts_direction and args.rfc2217 is None:
        raise UserError("--rts-direction needs --rfc2217 PORT (a pty has no RTS line)")
    if args.world and args.scenario:
        raise UserError("give the scenario once: --world SCENARIO or --scenario SCENARIO")
    if args.duration is not None:
        scenario_mod.check_duration(args.duration, "--duration")
    path = args.world or args.scenario
    sc, seed, ids = scenario_from_flags(args, scenario_mod.load_scenario(path) if path else None)
    transport = (SerialPort(args.port, args.baud or DEFAULT_BAUD) if args.port is not None
                 else Tcp(args.tcp, args.host) if args.tcp is not None
                 else Rfc2217(args.rfc2217, args.host, args.rts_direction)
                 if args.rfc2217 is not None else Pty())
    hint = None
    if args.world:   # our firmware's settings for this scenario, as `hexhil run` sends them
        hint = "firmware --config " + json.dumps(sc.firmware_settings(), sort_keys=True)

    def announce(line: str) -> None:
        flush_print(line)
        if hint:
            flush_print(hint)

    can_server = None
    if args.can_server is not None:
        from hexhil.run_summary import start_can_server
        can_server = start_can_server(args.can_server, 0)
    try:
        rt = RealTimeRun(sc, seed, world=args.world is not None, ids=ids, trace=args.out,
                         can_server=can_server, sensor_id=_sensor_id(args, sc),
                         duration_s=args.duration, overwrite=args.overwrite,
                         verbose=(lambda line: sys.stderr.write(line + "\n")) if args.verbose
                         else None)
        serial_server.install_sigterm()
        if args.inject_stdin:
            import threading

            threading.Thread(target=_read_injections, args=(rt,), daemon=True).start()
        s = rt.serve(transport, announce).as_dict()
    finally:
        if can_server is not None:
            can_server.close()
    st, p, v = s["bus"], s["pacing"], s["violations"]
    counts = ", ".join(f"{k} {n}" for k, n in sorted(s["faults"].items())) or "none"
    wrong = ", ".join(f"{k} {n}" for k, n in v["counts"].items() if n) or "none"
    if "body" in s:
        b = s["body"]
        flush_print(
            f"body: dx {b['dx_m']:+.3f} m, dy {b['dy_m']:+.3f} m, dyaw {b['dyaw_deg']:+.1f} deg "
            f"in {s['served_s']:.1f} s; pacing: lag p99 {p['p99_lag_ms']:.2f} ms, max "
            f"{p['max_lag_ms']:.2f} ms, {p['late_steps']} late of {p['advances']}")
        warning = lag_warning(p)
        if warning:
            sys.stderr.write(warning + "\n")
    lag = ""
    if p["late_replies"] or p["deferred_packets"]:
        lag = (f"; host lag (not the line's): {p['late_replies']} replies over "
               f"{p['late_threshold_ms']:g} ms late (max {p['max_reply_lag_ms']:.1f} ms), "
               f"{p['deferred_packets']} packets waited for a status")
    flush_print(
        f"served {st['packets']} packets, {st['replies']} replies, {st['collisions']} collisions, "
        f"{st['bad_checksum']} bad checksums; faults: {counts}; master violations: {wrong}{lag}")
    if args.json:
        cli.emit_json(s)
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bus", help="serve emulated Dynamixel servos (Protocol 1.0 or 2.0) on a "
                                   "pty or TCP port",
                       description="Serve emulated Dynamixel servos of any model in "
                                   "protocol/dynamixel/models.py (Protocol 1.0 or 2.0) in real "
                                   "time (wire time and return delay honoured) for stock "
                                   "Dynamixel clients.")
    p.add_argument("--servos", type=int, default=None, help="number of servos (default 18)")
    p.add_argument("--ids", default=None, help="servo IDs, e.g. 1-18 or 1,3,5-7")
    p.add_argument("--pty", action="store_true", help="serve on a pseudo-terminal, the default (prints 'pty: PATH')")
    p.add_argument("--tcp", type=int, default=None, metavar="PORT", help="serve on a TCP port")
    p.add_argument("--rfc2217", type=int, default=None, metavar="PORT",
                   help="serve pyserial's RFC 2217 (clients open rfc2217://127.0.0.1:PORT and "
                        "set baud, RTS, DTR: for clients that drive modem lines)")
    p.add_argument("--rts-direction", action="store_true",
                   help="with --rfc2217: RTS is the direction line (high: transmit), judged "
                        "like the board's PA1")
    p.add_argument("--port", default=None, metavar="DEVICE",
                   help="serve a real serial port through pyserial (a board's servo UART on a "
                        "USB adapter); --baud sets its rate")
    p.add_argument("--world", default=None, metavar="SCENARIO",
                   help="the scenario's MuJoCo world, paced to the wall clock (hexapod scenarios)")
    p.add_argument("--duration", type=float, default=None, metavar="S",
                   help="stop after S seconds of the master's time (from its first byte), "
                        "or after S seconds with no master at all (default: until "
                        "Ctrl-C/SIGTERM)")
    p.add_argument("--out", default=None, metavar="FILE.mcap",
                   help="record serial, CAN, ground truth, switches, faults and violations")
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    p.add_argument("--json", action="store_true", help=JSON_HELP)
    p.add_argument("--can-server", type=int, nargs="?", const=DEFAULT_PORT, metavar="PORT",
                   help="serve the rig's CAN bus (limit_switches frames) over socketcand "
                        f"(default port {DEFAULT_PORT}; 0 picks a free one)")
    p.add_argument("--sensor-id", type=int, default=None, metavar="ID",
                   help="the limit-switch sensor node's ID (default 100; on with --world)")
    p.add_argument("--no-sensor-node", action="store_true", help="no sensor node on the bus")
    p.add_argument("--host", default="127.0.0.1",
                   help="address for --tcp and --rfc2217 (default 127.0.0.1)")
    p.add_argument("--baud", type=int, default=None, help="line rate in bit/s (default 1000000)")
    p.add_argument("--echo", action="store_true", help="echo the master's bytes (single-wire adapter)")
    p.add_argument("--scenario", default=None, help="scenario TOML ([bus], [faults], [scenario].seed)")
    p.add_argument("--model", choices=tuple(models.MODELS), default=None,
                   help="servo model: " + ", ".join(
                       f"{m} (Protocol {v}.0)" for m, (_, v) in models.MODELS.items())
                   + f"; default {models.DEFAULT}; the sensor node is Protocol 1.0 only")
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
    p.add_argument("--inject-stdin", action="store_true",
                   help="read faults from stdin while serving, one a line: KIND key=value ... "
                        "(e.g. 'brownout id=3', 'switch_stuck leg=0 pressed=true until_s=9'; "
                        "docs/servo-bus.md, Fault vocabulary)")
    p.add_argument("-v", "--verbose", action="store_true", help="print each injected fault on stderr")
    p.set_defaults(func=run)
