"""The master check on a real master's traffic (``hexhil conformance --capture FILE``): a
logic analyser's capture of the servo line (``.sr``) or a trace's ``/serial``.

The master's packets go, at their captured times, through the same ``MasterCheck`` a run
feeds (hil/servobus/master_check.py), over emulated servos of the line's model that hear
them too, so an EEPROM write makes its servo deaf for the model's time and a write it
refuses is a ``bad_write``, as in a run. Whether a status was still arriving when the
master spoke is judged from the captured replies themselves, not the model's. Beside the
violations, what only a capture shows: bytes with a low stop bit (collisions, or noise),
each servo's return delays as measured, and pings and reads that got no reply.
"""
from __future__ import annotations

import bisect
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hexhil.hil.run import rig
from hexhil.hil.servobus.line import Bus
from hexhil.hil.servobus.master_check import MasterCheck
from hexhil.hil.servobus.wire import US_BITS
from hexhil.dynamixel.decode import DECODERS, packet_spans
from hexhil.trace.servo_capture import LineBurst, ServoLine
from hexhil.protocol.dynamixel import models
from hexhil.protocol.dynamixel import v1 as dxl
from hexhil.protocol.dynamixel import v2 as dx2
from hexhil.protocol.errors import BadValue

EVENTS_SHOWN = 20
# instructions no servo answers; of the rest, a PING or READ (the same codes in both
# protocols) is answered at every Status Return Level but 0, so one without a reply counts
NO_STATUS = (dxl.SYNC_WRITE, dx2.BULK_WRITE)


@dataclass
class _Line:
    """What the check asks of a bus, answered from the capture: the servos (emulated),
    each byte's time and whether a captured status is still arriving at ``now_us``."""

    bus: Bus
    replies: list[tuple[int, int]]   # (start_us, end_us) of each captured status, in order
    now_us: int = 0

    def __post_init__(self) -> None:
        self._starts = [s for s, _ in self.replies]

    @property
    def servos(self) -> list:
        return self.bus.servos

    def byte_end_us(self, start_us: int, i: int) -> int:
        return start_us + ((i + 1) * US_BITS) // self.bus.baud

    def reply_end_us(self) -> int | None:
        """The end of the captured status on the line at ``now_us`` (the one begun last
        before it: statuses on one line follow each other), or None."""
        k = bisect.bisect_left(self._starts, self.now_us) - 1
        if k < 0 or self.replies[k][1] <= self.now_us:
            return None
        return self.replies[k][1]


def load_line(path: str | Path, map_path: str | Path | None = None) -> ServoLine:
    """A capture's servo traffic: a ``.sr`` decoded, or an MCAP trace's ``/serial``."""
    from hexhil.trace import import_logs

    p = Path(path)
    if p.suffix.lower() == ".mcap":
        return _trace_line(p)
    maps = import_logs.load_map(map_path)
    return import_logs.read_servo_line(p, maps.get("serial"),
                                       str(map_path) if map_path else "map")


def _trace_line(path: Path) -> ServoLine:
    import json

    from hexhil.trace.protobuf import SerialBytes
    from hexhil.trace.reader import Trace
    from hexhil.trace.topics import T_SERIAL

    with Trace(path) as tr:
        if T_SERIAL not in tr.topics():
            raise BadValue(f"{path}: no {T_SERIAL} topic: no servo-line traffic to check")
        meta = tr.metadata()
        bursts = []
        for m in tr.messages([T_SERIAL]):
            s = SerialBytes.FromString(m.data)
            if s.data:
                bursts.append(LineBurst(m.log_time_ns // 1000, s.direction, bytes(s.data)))
    try:
        bus = json.loads(meta.get("scenario_data", "{}")).get("bus", {})
    except ValueError:
        bus = {}
    model = bus.get("model", models.DEFAULT)
    baud = int(meta.get("baud", bus.get("baud", 1_000_000)))
    if not bursts:
        raise BadValue(f"{path}: {T_SERIAL} holds no bytes")
    return ServoLine(baud, models.protocol(model), tuple(bursts), (), "trace", "trace")


def _runs(data: bytes, protocol: int) -> list[tuple[int, int, bool]]:
    """(offset, length, is_packet) runs covering ``data``: its packets and the bytes between."""
    out, at = [], 0
    for off, n, _ in packet_spans(data, protocol):
        if off > at:
            out.append((at, off - at, False))
        out.append((off, n, True))
        at = off + n
    if at < len(data):
        out.append((at, len(data) - at, False))
    return out


def _servo_ids(line: ServoLine, given: list[int] | None) -> list[int]:
    """The servos to emulate: ``given``, else every ID that answered in the capture, else
    every ID the master addressed."""
    if given:
        return sorted(set(given))
    codec = dx2 if line.protocol == 2 else dxl
    answered, addressed = set(), set()
    for b in line.bursts:
        p = codec.Parser()
        for byte in b.data:
            if p.push(byte):
                dev = p.current().id
                (answered if b.direction == "rx" else addressed).add(dev)
    ids = answered or addressed
    ids.discard(codec.BROADCAST_ID)
    if not ids:
        raise BadValue("the capture holds no packet to a servo: nothing to check")
    return sorted(ids)


def check_capture(path: str | Path, model: str | None = None, ids: list[int] | None = None,
                  map_path: str | Path | None = None) -> dict[str, Any]:
    """The master check's report on a capture (the module docstring says what is checked):
    ``ok`` when the master broke no rule and no byte was garbled."""
    line = load_line(path, map_path)
    if model is None:
        model = models.default_model(line.protocol)
    elif model not in models.MODELS:
        raise BadValue(f"unknown servo model {model!r} (one of {', '.join(models.MODELS)})",
                       params=("model",))
    elif models.protocol(model) != line.protocol:
        raise BadValue(f"{path}: the capture is Protocol {line.protocol}.0, model {model} "
                       f"speaks {models.protocol(model)}.0", params=("model",))
    servo_ids = _servo_ids(line, ids)
    built = rig.build({"_path": str(path), "bus": {"model": model, "baud": line.baud}},
                      ids=servo_ids)
    bus = built.bus
    t0 = line.bursts[0].t_us
    replies = [(b.t_us - t0, b.t_us - t0 + bus.wire_us(len(b.data)))
               for b in line.bursts if b.direction == "rx"]
    view = _Line(bus, replies)
    names, table = DECODERS[line.protocol].names, models.table(model)
    events: list[dict[str, Any]] = []
    current = {"words": ""}

    def named(t_us: int, kind: str, detail: str) -> None:
        if len(events) < EVENTS_SHOWN:
            events.append({"t_s": round(t_us * 1e-6, 6), "kind": kind, "detail": detail,
                           "packet": current["words"]})

    check = MasterCheck(named, protocol=line.protocol)
    delays: dict[int, list[int]] = {}
    unanswered = 0
    awaiting: tuple[int, int, bool] | None = None   # the last instruction: id, end, a read
    codec = dx2 if line.protocol == 2 else dxl
    for b in line.bursts:
        t = b.t_us - t0
        if b.direction == "rx":
            if awaiting is not None:
                p = codec.Parser()
                got = [p.current().id for byte in b.data if p.push(byte)]
                if awaiting[0] in got:
                    delays.setdefault(awaiting[0], []).append(t - awaiting[1])
                    awaiting = None
            continue
        if awaiting is not None:
            unanswered += awaiting[2]
            awaiting = None
        for off, n, is_packet in _runs(b.data, line.protocol):
            chunk = b.data[off:off + n]
            at = t + (off * US_BITS) // bus.baud
            if at > bus.clock.t_us:
                bus.idle_until(at)
            bus.master_discard()
            view.now_us = at
            current["words"] = "; ".join(names(chunk, table)) if is_packet else chunk.hex()
            check.master_bytes(view, at, chunk)
            bus.master_write(chunk)
            if is_packet:
                dev = chunk[2] if line.protocol == 1 else chunk[4]
                code = chunk[4] if line.protocol == 1 else chunk[7]
                if dev != codec.BROADCAST_ID and code not in NO_STATUS:
                    awaiting = (dev, at + bus.wire_us(n), code in (dxl.PING, dxl.READ))
    summary = check.summary()
    summary["events"] = events
    framing = len(line.framing_errors_us)
    return {"capture": str(path), "baud": line.baud, "protocol": line.protocol, "model": model,
            "servos": servo_ids, "data_channel": line.data_channel,
            "direction_channel": line.direction_channel,
            "master_bursts": sum(1 for b in line.bursts if b.direction == "tx"),
            "violations": summary,
            "line": {"framing_errors": framing,
                     "first_framing_error_s": round((line.framing_errors_us[0] - t0) * 1e-6, 6)
                     if framing else None,
                     "unanswered": unanswered,
                     "return_delay_us": {str(i): {"min": min(d), "max": max(d), "n": len(d)}
                                         for i, d in sorted(delays.items())}},
            "ok": summary["total"] == 0 and framing == 0}

