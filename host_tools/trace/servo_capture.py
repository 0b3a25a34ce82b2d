"""A captured servo line as half-duplex Dynamixel traffic: the UART bytes of one data line
(host_tools/trace/logic_capture.py) cut into bursts, each the master's (``tx``) or the
servos' (``rx``), with the time of its first byte.

Who sent a byte: with a direction channel (the adapter's transmit-enable: high while the
master drives the line) its level at the byte's start bit; without one, the packets say
it. Protocol 2.0 marks a status packet (instruction 0x55); Protocol 1.0 instruction and
status packets look alike, and host_tools/dynamixel/decode/v1.py's rule decides (a packet
from the id the last instruction went to, as long as its reply, is that reply). Bytes in
no packet (noise, a collision) go with the bytes before them.

A burst is bytes back to back: a byte that starts more than one bit after the previous
one's stop bit, or another sender's, starts a new burst, so every byte's time is its
burst's time plus its place in it (the trace's ``/serial`` and the bus model's timing).
"""
from __future__ import annotations

from dataclasses import dataclass

from hexhil.dynamixel.decode import guess_protocol, packet_spans
from hexhil.dynamixel.decode import v1 as decode_v1
from hexhil.trace.logic_capture import (BITS_PER_BYTE, LogicCapture, UartByte,
                                            decode_uart, find_baud)
from hexhil.protocol.errors import BadValue, UserError

DIRECTION_NAMES = ("dir", "direction", "de", "txen", "tx_en", "rts")
DATA_NAMES = ("data", "dxl", "line", "bus")


@dataclass(frozen=True)
class LineBurst:
    t_us: int
    direction: str     # "tx" master -> servos, "rx" servos -> master
    data: bytes


@dataclass(frozen=True)
class ServoLine:
    """A capture's servo traffic and how it was read."""

    baud: int
    protocol: int
    bursts: tuple[LineBurst, ...]
    framing_errors_us: tuple[int, ...]   # bytes whose stop bit was low
    data_channel: str
    direction_channel: str | None


@dataclass(frozen=True)
class LineMap:
    """How to read a capture (the map file's ``[serial]``; every key may be left out)."""

    data: str | None = None        # channel name or number of the data line
    direction: str | None = None   # channel of the direction line ("none": there is none)
    baud: int | None = None        # bit/s; found from the edges when left out
    protocol: int | None = None    # 1 or 2; guessed from the headers when left out


def _named(capture: LogicCapture, names: tuple[str, ...]) -> int | None:
    for i, ch in enumerate(capture.channels):
        if ch.lower() in names:
            return i
    return None


def _direction_bit(capture: LogicCapture, data_bit: int, given: str | None) -> int | None:
    """The direction channel: the one the map names, else one named like it, else the
    third channel where the capture has one that changes level."""
    if given is not None:
        if given.lower() == "none":
            return None
        bit = capture.channel(given)
        if bit == data_bit:
            raise BadValue(f"{capture.path}: the direction channel is the data channel")
        return bit
    bit = _named(capture, DIRECTION_NAMES)
    if bit is None and len(capture.channels) >= 3 and data_bit != 2:
        bit = 2
    if bit is None or bit == data_bit:
        return None
    lv = capture.levels(bit)
    return bit if lv.min() != lv.max() else None


def _senders_by_packets(values: bytes, protocol: int) -> list[str]:
    """Each byte's sender ("tx"/"rx") read from the packets the bytes form."""
    who = [""] * len(values)
    if protocol == 2:
        for off, n, status in packet_spans(values, 2):
            who[off:off + n] = ["rx" if status else "tx"] * n
    else:
        try:
            parts = decode_v1.split_stream(values, lenient=True)
        except UserError:
            parts = []
        packets = [p for p in parts if p[0] == "packet"]
        kinds = decode_v1.classify([p[2] for p in packets])
        for (_, offset, pkt, _), rec in zip(packets, kinds):
            kind = "rx" if rec["kind"] == "status" else "tx"
            who[offset:offset + len(pkt.raw)] = [kind] * len(pkt.raw)
    last = "tx"
    for i, w in enumerate(who):
        who[i] = last = w or last
    return who


def _bursts(data: list[UartByte], senders: list[str], bps: int) -> list[LineBurst]:
    byte_ns = BITS_PER_BYTE * 1e9 / bps
    slack_ns = 1e9 / bps    # up to a bit of idle between bytes of one burst
    out: list[LineBurst] = []
    start_ns = prev_ns = 0
    cur = bytearray()
    sender = ""
    for b, who in zip(data, senders):
        if cur and (who != sender or b.start_ns - prev_ns > byte_ns + slack_ns):
            out.append(LineBurst(int(round(start_ns / 1000)), sender, bytes(cur)))
            cur = bytearray()
        if not cur:
            start_ns, sender = b.start_ns, who
        cur.append(b.value)
        prev_ns = b.start_ns
    if cur:
        out.append(LineBurst(int(round(start_ns / 1000)), sender, bytes(cur)))
    return out


def decode_line(capture: LogicCapture, line: LineMap = LineMap()) -> ServoLine:
    """The capture's Dynamixel traffic (the module docstring says how it is read)."""
    data_bit = capture.channel(line.data) if line.data is not None else (
        _named(capture, DATA_NAMES) or 0)
    bps = line.baud if line.baud is not None else find_baud(capture, data_bit)
    if bps <= 0:
        raise BadValue(f"{capture.path}: baud must be positive, got {bps}")
    data = decode_uart(capture, data_bit, bps)
    if not data:
        raise BadValue(f"{capture.path}: no bytes on channel {capture.channels[data_bit]} "
                       f"at {bps} bit/s")
    values = bytes(b.value for b in data)
    protocol = line.protocol if line.protocol is not None else guess_protocol(values)
    if protocol not in (1, 2):
        raise BadValue(f"{capture.path}: protocol must be 1 or 2, got {protocol}")
    dir_bit = _direction_bit(capture, data_bit, line.direction)
    if dir_bit is not None:
        lv = capture.levels(dir_bit)
        per_ns = capture.samplerate_hz / 1e9
        senders = ["tx" if lv[min(len(lv) - 1, int(b.start_ns * per_ns))] else "rx"
                   for b in data]
    else:
        senders = _senders_by_packets(values, protocol)
    bursts = _bursts(data, senders, bps)
    if not any(b.direction == "tx" for b in bursts):
        raise BadValue(f"{capture.path}: no master packet in {len(values)} bytes at {bps} "
                       "bit/s: not a Dynamixel line at this baud")
    return ServoLine(bps, protocol, tuple(bursts),
                     tuple(int(round(b.start_ns / 1000)) for b in data if not b.framing_ok),
                     capture.channels[data_bit],
                     capture.channels[dir_bit] if dir_bit is not None else None)
