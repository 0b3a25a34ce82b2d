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

from host_tools.cli import JSON_HELP, actions, emit, emit_json
from protocol.errors import UserError
from protocol.dynamixel import ax12
from protocol.dynamixel import v1 as dxl

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
                raise UserError(f"not hex: {bad!r} in {token!r} (argument {n})")
            digits.append(token)
    text = "".join(digits)
    if not text:
        raise UserError("no hex digits given")
    if len(text) % 2:
        raise UserError(f"odd number of hex digits ({len(text)}): each byte needs two")
    return bytes.fromhex(text)


def _fmt(data: bytes) -> str:
    return " ".join(f"{b:02X}" for b in data)


def _malformed(data: bytes, j: int, next_packet: int | None) -> str | None:
    """Why a header candidate at ``data[j]`` is no packet, or None if ``j`` starts no header."""
    if data[j] != dxl.HEADER or j + 1 >= len(data) or data[j + 1] != dxl.HEADER:
        return None
    if j + 2 < len(data) and data[j + 2] == dxl.HEADER:
        return None  # FF FF FF: a header may start one byte later
    if j + 4 > len(data):
        return f"truncated packet at byte {j}: {len(data) - j} bytes, no room for ID and LEN"
    dev_id, length = data[j + 2], data[j + 3]
    if length < 2:
        return f"bad length at byte {j}: LEN {length} (id {dev_id}), the least is 2"
    end = j + length + 4
    if next_packet is not None and end > next_packet:
        return (f"bad packet at byte {j} (id {dev_id}): LEN {length} runs into the packet "
                f"at byte {next_packet}")
    if end > len(data):
        return (f"truncated packet at byte {j} (id {dev_id}): LEN {length} needs {length + 4} "
                f"bytes, {len(data) - j} given")
    want = dxl.checksum(data, j + 2, end - 1)
    return (f"bad checksum at byte {j} (id {dev_id}): 0x{data[end - 1]:02X}, "
            f"expected 0x{want:02X}")


def split_stream(data: bytes, lenient: bool = False) -> list[tuple[str, int, Any, str | None]]:
    """``[("packet", offset, Packet, None) | ("garbage", offset, bytes, reason)]`` in order.

    Raises UserError for the first malformed packet (bad length or checksum, truncated),
    unless ``lenient``: then its reason goes with the garbage that holds it.
    """
    parser = dxl.Parser()
    found: list[tuple[int, dxl.Packet]] = []
    for i, b in enumerate(data):
        if parser.push(b):
            pkt = parser.current()
            found.append((i + 1 - len(pkt.raw), pkt))
    pos = found[-1][0] + len(found[-1][1].raw) if found else 0
    for pkt in parser.flush():  # packets hidden behind a garbage header's long LEN
        start = data.find(pkt.raw, pos)
        found.append((start, pkt))
        pos = start + len(pkt.raw)
    out: list[tuple[str, int, Any, str | None]] = []
    pos = 0
    for k in range(len(found) + 1):
        start = found[k][0] if k < len(found) else len(data)
        if start > pos:
            reasons = [_malformed(data, j, start if k < len(found) else None)
                       for j in range(pos, start)]
            why = next((r for r in reasons if r), None)
            if why and not lenient:
                raise UserError(why)
            out.append(("garbage", pos, data[pos:start], why))
        if k < len(found):
            out.append(("packet", start, found[k][1], None))
            pos = start + len(found[k][1].raw)
    if not any(part[0] == "packet" for part in out):
        raise UserError(f"no Dynamixel packet in {len(data)} bytes (no FF FF header)")
    return out


def _field(address: int) -> str | None:
    f = ax12.field_at(address)
    return f[1] if f else None


def describe(pkt: dxl.Packet, kind: str, reply_to: dxl.Packet | None = None) -> dict[str, Any]:
    """A packet as a JSON-ready dict (the ``--json`` record)."""
    params = list(pkt.params)
    d: dict[str, Any] = {"id": pkt.id, "kind": kind, "params": params, "raw": pkt.raw.hex()}
    if kind == "status":
        d["error"] = dxl.error_names(pkt.code)
        if reply_to is not None:
            d["reply_to"] = dxl.INSTRUCTION_NAMES[reply_to.code]
            if reply_to.code == dxl.READ and len(reply_to.params) == 2:
                d["address"] = reply_to.params[0]
                d["register"] = _field(reply_to.params[0])
        return d
    name = dxl.INSTRUCTION_NAMES.get(pkt.code)
    d["instruction"] = name if name else f"UNKNOWN_0x{pkt.code:02X}"
    if pkt.code == dxl.READ and len(params) == 2:
        d.update(address=params[0], register=_field(params[0]), length=params[1])
    elif pkt.code in (dxl.WRITE, dxl.REG_WRITE) and params:
        d.update(address=params[0], register=_field(params[0]), data=params[1:])
    elif pkt.code == dxl.SYNC_WRITE and len(params) >= 2:
        address, n = params[0], params[1]
        body = params[2:]
        if n and len(body) % (n + 1) == 0:
            entries = [{"id": body[i], "data": body[i + 1:i + 1 + n]}
                       for i in range(0, len(body), n + 1)]
        else:
            raise UserError(f"bad SYNC_WRITE (id {pkt.id}): {len(body)} parameter bytes are no "
                            f"whole number of {n}-byte entries plus ids")
        d.update(address=address, register=_field(address), length=n, entries=entries)
    return d


def _is_reply(pkt: dxl.Packet, previous: dxl.Packet | None) -> bool:
    """Could ``pkt`` be the status reply to the instruction ``previous``?"""
    if previous is None or previous.id == dxl.BROADCAST_ID or pkt.id != previous.id:
        return False
    if previous.code == dxl.READ and len(previous.params) == 2:
        return len(pkt.params) == previous.params[1]
    return previous.code in dxl.INSTRUCTION_NAMES and not pkt.params


def classify(packets: list[dxl.Packet], force: str | None = None) -> list[dict[str, Any]]:
    """Describe each packet, deciding instruction/status by the module docstring's rule."""
    out = []
    previous: dxl.Packet | None = None  # the last packet taken as an instruction
    for pkt in packets:
        reply_to = None
        if force:
            kind = force
        elif _is_reply(pkt, previous):
            kind, reply_to = "status", previous
        elif pkt.code in dxl.INSTRUCTION_NAMES:
            kind = "instruction"
        else:
            kind = "status"
        out.append(describe(pkt, kind, reply_to))
        previous = pkt if kind == "instruction" else None
    return out


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


def decode2(args: argparse.Namespace, data: bytes) -> int:
    """Protocol 2.0 bytes (host_tools/decode2.py), one line (or JSON object) a record."""
    from host_tools.decode2 import decode as decode_v2

    records = decode_v2(data)
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


def decode(args: argparse.Namespace) -> int:
    from host_tools.decode2 import looks_like_protocol_2

    data = parse_hex(args.hex)
    if args.protocol == 2 or (args.protocol is None and looks_like_protocol_2(data)):
        return decode2(args, data)
    parts = split_stream(data, args.lenient)
    force = "status" if args.status else ("instruction" if args.instruction else None)
    records = iter(classify([p[2] for p in parts if p[0] == "packet"], force))
    n_packets = n_garbage = 0
    for kind, offset, item, why in parts:
        if kind == "garbage":
            n_garbage += len(item)
            if args.json:
                emit_json({"kind": "garbage", "offset": offset, "bytes": list(item),
                           "reason": why})
            else:
                print(f"@{offset:<4} garbage: {len(item)} bytes: {_fmt(item)}"
                      + (f"  ({why})" if why else ""))
            continue
        rec = next(records)
        n_packets += 1
        if args.json:
            emit_json(dict(rec, offset=offset))
        else:
            print(_text(rec, offset))
            print(f"      {_fmt(item.raw)}")
    summary = {"kind": "summary", "packets": n_packets, "garbage_bytes": n_garbage,
               "bytes": len(data)}
    emit(args, summary, f"{n_packets} packets, {n_garbage} garbage bytes, {len(data)} bytes")
    return 0


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
