"""Dynamixel Protocol 2.0 bytes decoded: each packet with its instruction, error names,
addresses and X-series register names, and the garbage between packets, as records for
humans (``hexhil protocol decode``); and the packets each serial burst completes for the
trace, in the same ``DynamixelPacket`` schema as Protocol 1.0's (v1.py)."""
from __future__ import annotations

from types import ModuleType
from typing import Any

from hexhil.dynamixel.decode.words import phrase
from hexhil.trace import protobuf as pb
from hexhil.protocol.dynamixel import v2 as dx2
from hexhil.protocol.dynamixel import xl430 as xl

HEADER = b"\xff\xff\xfd\x00"


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
            end = i + 1 - parser.pending()   # a packet inside a rejected header ends earlier
            begin = end - parser.raw_len
            if begin > start:
                out.append({"kind": "garbage", "offset": start, "bytes": list(data[start:begin])})
            out.append(dict(describe(parser.current()), offset=begin))
            start = end
    if start < len(data):
        out.append({"kind": "garbage", "offset": start, "bytes": list(data[start:])})
    return out


def names(data: bytes, table: ModuleType = xl) -> list[str]:
    """Each packet in ``data`` in words, its parameters against the control table ``table``
    (words.py: "SYNC_READ Present Position (132) 4 bytes ids 1-18"); garbage is left out
    (replay's divergences)."""
    return [phrase(r, table) for r in decode(data) if r["kind"] != "garbage"]


class TracePackets:
    """One direction's serial bytes cut into packets, encoded for the trace's ``/serial`` as
    Protocol 1.0's are (v1.py): an instruction's code is its instruction, a status packet's
    its error field (the parameters after it)."""

    def __init__(self, direction: str) -> None:
        self.direction = direction
        self.parser = dx2.Parser()

    def feed(self, data: bytes, t_us: int) -> list[bytes]:
        """The packets ``data`` completes (``data`` may end or start one)."""
        parser = self.parser
        return [self._encode(parser.current()) for b in data if parser.push(b, t_us)]

    def flush(self) -> list[bytes]:
        """Packets hidden behind a bad header, found at the end of the stream."""
        return [self._encode(p) for p in self.parser.flush()]

    def _encode(self, p: dx2.Packet) -> bytes:
        if p.instr == dx2.STATUS:
            return pb.encode_dynamixel_packet(self.direction, p.id, p.error, p.params[1:], p.raw,
                                              codec=dx2, status=True)
        return pb.encode_dynamixel_packet(self.direction, p.id, p.instr, p.params, p.raw,
                                          codec=dx2, status=False)
