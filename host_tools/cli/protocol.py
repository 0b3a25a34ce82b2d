"""``hexhil protocol decode HEX...``: Dynamixel Protocol 1.0 (or 2.0) bytes, explained for humans.

Anything that starts with ``FF FF`` is read as a packet and must be a good one (length,
checksum, complete), else the command fails with one line saying why (``--lenient``
reports it as garbage with the reason instead). Bytes that cannot start a packet are
garbage: reported, not fatal.

Protocol 1.0 instruction and status packets look alike on the wire, so the kind is decided
by this rule (``--status``/``--instruction`` force it):
1. a packet right after an instruction that gets a reply (not broadcast), from the same
   id and with as many parameters as that reply carries (READ: the bytes asked for; the
   others: none), is that instruction's status reply;
2. otherwise it is an instruction when its code is one of the seven AX-12 instructions;
3. otherwise it is a status packet (its code is the error byte).
"""
from __future__ import annotations

import argparse
import string
from typing import Any

from hexhil.cli import JSON_HELP, actions, emit, emit_json
from hexhil.dynamixel.decode import DECODERS, guess_protocol
from hexhil.protocol.errors import BadValue

HEXDIGITS = set(string.hexdigits)


def parse_hex(args: list[str]) -> bytes:
    """Hex from one or several arguments, with or without spaces, ``0x`` prefixes, ``:`` or ``,``."""
    digits = []
    for n, arg in enumerate(args, 1):
        for token in arg.replace(",", " ").replace(":", " ").split():
            if token[:2].lower() == "0x":
                token = token[2:]
            bad = next((c for c in token if c not in HEXDIGITS), None)
            if bad is not None:
                raise BadValue(f"not hex: {bad!r} in {token!r} (argument {n})")
            digits.append(token)
    text = "".join(digits)
    if not text:
        raise BadValue("no hex digits given")
    if len(text) % 2:
        raise BadValue(f"odd number of hex digits ({len(text)}): each byte needs two")
    return bytes.fromhex(text)


def _fmt(data: bytes) -> str:
    return " ".join(f"{b:02X}" for b in data)


def _text(rec: dict[str, Any], offset: int) -> str:
    head = f"@{offset:<4} id {rec['id']:>3}  "
    reg = f" ({rec['register']})" if rec.get("register") else ""
    if rec["kind"] == "status":
        err = ",".join(rec["error"]) or "ok"
        line = f"{head}status      error={err} params={rec['params']}"
        if "reply_to" in rec:
            line += f"  reply to {rec['reply_to']}" + (f" of {rec['address']}{reg}"
                                                       if "address" in rec else "")
        return line
    name = rec["instruction"]
    line = f"{head}instruction {name}"
    if "entries" in rec:
        line += f" address={rec['address']}{reg} length={rec['length']} to {len(rec['entries'])} ids"
        for e in rec["entries"]:
            line += f"\n      id {e['id']:>3}: {_fmt(bytes(e['data']))}"
    elif "length" in rec:
        line += f" address={rec['address']}{reg} length={rec['length']}"
    elif "data" in rec:
        line += f" address={rec['address']}{reg} data={_fmt(bytes(rec['data']))}"
    elif rec["params"]:
        line += f" params={rec['params']}"
    return line


def print_v2(args: argparse.Namespace, data: bytes) -> int:
    """Protocol 2.0 bytes (host_tools/dynamixel/decode/v2.py), one line (or JSON object) a record."""
    records = DECODERS[2].decode(data)
    for rec in records:
        if args.json:
            emit_json(rec)
        elif rec["kind"] == "garbage":
            print(f"@{rec['offset']:<4} garbage: {len(rec['bytes'])} bytes: {_fmt(bytes(rec['bytes']))}")
        else:
            what = {k: v for k, v in rec.items() if k not in ("kind", "id", "instruction", "raw",
                                                              "offset")}
            print(f"@{rec['offset']:<4} id {rec['id']:>3}  {rec['kind']} {rec['instruction']} "
                  + " ".join(f"{k}={v}" for k, v in what.items() if v is not None))
            print(f"      {rec['raw']}")
    n = sum(r["kind"] != "garbage" for r in records)
    g = sum(len(r["bytes"]) for r in records if r["kind"] == "garbage")
    emit(args, {"kind": "summary", "protocol": 2, "packets": n, "garbage_bytes": g,
                "bytes": len(data)}, f"{n} packets (Protocol 2.0), {g} garbage bytes, "
                                     f"{len(data)} bytes")
    return 0


def print_v1(args: argparse.Namespace, data: bytes) -> int:
    """Protocol 1.0 bytes (host_tools/dynamixel/decode/v1.py), one line (or JSON object) a record."""
    force = "status" if args.status else ("instruction" if args.instruction else None)
    records = DECODERS[1].decode(data, args.lenient, force)
    for rec in records:
        if rec["kind"] == "garbage":
            if args.json:
                emit_json(rec)
            else:
                why = rec["reason"]
                print(f"@{rec['offset']:<4} garbage: {len(rec['bytes'])} bytes: "
                      f"{_fmt(bytes(rec['bytes']))}" + (f"  ({why})" if why else ""))
        elif args.json:
            emit_json(rec)
        else:
            print(_text(rec, rec["offset"]))
            print(f"      {_fmt(bytes.fromhex(rec['raw']))}")
    n_packets = sum(r["kind"] != "garbage" for r in records)
    n_garbage = sum(len(r["bytes"]) for r in records if r["kind"] == "garbage")
    summary = {"kind": "summary", "packets": n_packets, "garbage_bytes": n_garbage,
               "bytes": len(data)}
    emit(args, summary, f"{n_packets} packets, {n_garbage} garbage bytes, {len(data)} bytes")
    return 0


PRINTERS = {1: print_v1, 2: print_v2}


def decode(args: argparse.Namespace) -> int:
    data = parse_hex(args.hex)
    return PRINTERS[args.protocol or guess_protocol(data)](args, data)


def register(sub: argparse._SubParsersAction) -> None:
    psub = actions(sub, "protocol", "Dynamixel tools (decode Protocol 1.0 and 2.0)",
                       "SUBCOMMAND", "Dynamixel tools, Protocol 1.0 and 2.0.")
    d = psub.add_parser("decode", help="decode Dynamixel packets given as hex",
                        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    d.add_argument("hex", nargs="+", metavar="HEX",
                   help="bytes as hex: 'FF FF 01 02 01 FB' or ffff010201fb, one or several args")
    d.add_argument("--json", action="store_true",
                   help=JSON_HELP + "; before it one object a line for each packet and garbage run")
    kind = d.add_mutually_exclusive_group()
    kind.add_argument("--status", action="store_true", help="every packet is a status packet")
    kind.add_argument("--instruction", action="store_true",
                      help="every packet is an instruction packet")
    d.add_argument("--protocol", type=int, choices=(1, 2), default=None,
                   help="Dynamixel protocol (default: 2 when FF FF FD 00 appears, else 1)")
    d.add_argument("--lenient", action="store_true",
                   help="report malformed packets as garbage (with the reason) instead of failing")
    d.set_defaults(func=decode)
