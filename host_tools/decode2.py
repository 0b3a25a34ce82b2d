"""Dynamixel Protocol 2.0 bytes as records for humans (``hexhil protocol decode``): each
packet with its instruction, error names, addresses and XL430 register names, and the
garbage between packets."""
from __future__ import annotations

from typing import Any

from protocol.dynamixel import v2 as dx2
from protocol.dynamixel import xl430 as xl


def register(address: int) -> str | None:
    f = xl.BY_ADDRESS.get(address)
    return f[1] if f is not None else None


def describe(pkt: dx2.Packet) -> dict[str, Any]:
    """One packet as a JSON-ready dict."""
    p = pkt.params
    d: dict[str, Any] = {"id": pkt.id, "instruction": dx2.INSTRUCTION_NAMES.get(
        pkt.instr, f"0x{pkt.instr:02X}"), "raw": pkt.raw.hex(" ")}
    if pkt.instr == dx2.STATUS:
        d["kind"] = "status"
        d["error"] = dx2.error_names(pkt.error)
        if pkt.id == dx2.BROADCAST_ID:
            d["fast_reply"] = True
        d["params"] = list(p[1:])
        return d
    d["kind"] = "instruction"
    if pkt.instr in (dx2.READ, dx2.SYNC_READ, dx2.FAST_SYNC_READ) and len(p) >= 4:
        d.update(address=p[0] | p[1] << 8, length=p[2] | p[3] << 8, register=register(p[0] | p[1] << 8))
        if pkt.instr != dx2.READ:
            d["ids"] = list(p[4:])
    elif pkt.instr in (dx2.WRITE, dx2.REG_WRITE) and len(p) >= 2:
        d.update(address=p[0] | p[1] << 8, register=register(p[0] | p[1] << 8), data=list(p[2:]))
    elif pkt.instr == dx2.SYNC_WRITE and len(p) >= 4:
        a, n = p[0] | p[1] << 8, p[2] | p[3] << 8
        d.update(address=a, length=n, register=register(a),
                 entries=[{"id": p[i], "data": list(p[i + 1:i + 1 + n])}
                          for i in range(4, len(p) - n, n + 1)] if n else [])
    elif pkt.instr in (dx2.BULK_READ, dx2.FAST_BULK_READ, dx2.BULK_WRITE):
        entries, i = [], 0
        while i + 5 <= len(p):
            a, n = p[i + 1] | p[i + 2] << 8, p[i + 3] | p[i + 4] << 8
            e: dict[str, Any] = {"id": p[i], "address": a, "length": n, "register": register(a)}
            if pkt.instr == dx2.BULK_WRITE:
                e["data"] = list(p[i + 5:i + 5 + n])
                i += n
            entries.append(e)
            i += 5
        d["entries"] = entries
    else:
        d["params"] = list(p)
    return d


def decode(data: bytes) -> list[dict[str, Any]]:
    """Packets and garbage runs in stream order, each with its byte offset."""
    parser = dx2.Parser()
    out: list[dict[str, Any]] = []
    start = 0          # where the bytes not yet accounted for begin
    for i, b in enumerate(data):
        if parser.push(b):
            begin = i + 1 - parser.raw_len
            if begin > start:
                out.append({"kind": "garbage", "offset": start, "bytes": list(data[start:begin])})
            out.append(dict(describe(parser.current()), offset=begin))
            start = i + 1
    if start < len(data):
        out.append({"kind": "garbage", "offset": start, "bytes": list(data[start:])})
    return out


def looks_like_protocol_2(data: bytes) -> bool:
    return b"\xff\xff\xfd\x00" in data
