"""Dynamixel Protocol 1.0 bytes decoded: packets and garbage as records for humans
(``hexhil protocol decode``), and the packets each serial burst completes for the trace.

Protocol 1.0 instruction and status packets look alike on the wire, so the kind is decided
by this rule (``--status``/``--instruction`` force it):
1. a packet right after an instruction that gets a reply (not broadcast), from the same
   id and with as many parameters as that reply carries (READ: the bytes asked for; the
   others: none), is that instruction's status reply;
2. otherwise it is an instruction when its code is one of the seven AX-12 instructions;
3. otherwise it is a status packet (its code is the error byte).
"""
from __future__ import annotations

from types import ModuleType
from typing import Any

from hexhil.dynamixel.decode.words import phrase
from hexhil.trace import protobuf as pb
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl
from hexhil.protocol.errors import BadValue, UserError


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
            # a packet inside a garbage header's LEN ends before the bytes still held
            found.append((i + 1 - parser.pending() - len(pkt.raw), pkt))
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
                raise BadValue(why)
            out.append(("garbage", pos, data[pos:start], why))
        if k < len(found):
            out.append(("packet", start, found[k][1], None))
            pos = start + len(found[k][1].raw)
    if not any(part[0] == "packet" for part in out):
        raise BadValue(f"no Dynamixel packet in {len(data)} bytes (no FF FF header)")
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
            raise BadValue(f"bad SYNC_WRITE (id {pkt.id}): {len(body)} parameter bytes are no "
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


def decode(data: bytes, lenient: bool = False, force: str | None = None
           ) -> list[dict[str, Any]]:
    """Packets (``describe``'s records) and garbage runs (``bytes``, ``reason``) in stream
    order, each with its byte offset; ``force`` "status" or "instruction" decides every
    packet's kind."""
    parts = split_stream(data, lenient)
    records = iter(classify([p[2] for p in parts if p[0] == "packet"], force))
    out = []
    for kind, offset, item, why in parts:
        if kind == "garbage":
            out.append({"kind": "garbage", "offset": offset, "bytes": list(item), "reason": why})
        else:
            out.append(dict(next(records), offset=offset))
    return out


def names(data: bytes, table: ModuleType = ax12) -> list[str]:
    """Each packet in ``data`` in words, its parameters against the control table ``table``
    (words.py: "WRITE id 3 Goal Position (30) = 512"); malformed packets and garbage are
    left out (replay's divergences)."""
    try:
        records = decode(data, lenient=True)
    except UserError:        # not one packet in it
        return []
    return [phrase(r, table) for r in records if r["kind"] != "garbage"]


class TracePackets:
    """One direction's serial bytes cut into packets, encoded for the trace's ``/serial``
    (``SerialBytes.packets``: a status packet's code is its error byte)."""

    def __init__(self, direction: str) -> None:
        self.direction = direction
        self.parser = dxl.Parser()

    def feed(self, data: bytes, t_us: int) -> list[bytes]:
        """The packets ``data`` completes (``data`` may end or start one)."""
        parser, direction = self.parser, self.direction
        n = len(data)
        if (not parser.pending() and n >= 6 and data[0] == 0xFF and data[1] == 0xFF
                and data[2] != 0xFF and data[3] + 4 == n
                and (~sum(data[2:n - 1])) & 0xFF == data[n - 1]):
            # one whole valid packet, nothing held: what push() would find, ~20x faster
            return [pb.encode_dynamixel_packet(direction, data[2], data[4], data[5:n - 1], data)]
        found = []
        for b in data:
            if parser.push(b, t_us):
                end = dxl.PARAMS_OFFSET + parser.nparams
                buf = parser.buf
                found.append(pb.encode_dynamixel_packet(
                    direction, parser.id, parser.code,
                    bytes(buf[dxl.PARAMS_OFFSET:end]), bytes(buf[0:end + 1])))
        return found

    def flush(self) -> list[bytes]:
        """Packets hidden behind a bad header, found at the end of the stream."""
        return [pb.encode_dynamixel_packet(self.direction, p.id, p.code, p.params, p.raw)
                for p in self.parser.flush()]
