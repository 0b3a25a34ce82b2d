"""Replay a trace: into the firmware (regression test) or onto a CAN bus.

Into the firmware: the trace's ``/link`` topic holds every simulator-link exchange of the
run (``protocol/sim_link.py`` framing): the bytes the firmware sent since the previous
reply (posted UART writes, CAN frames, events, then the request) and the reply it got
(virtual time, bus bytes, switch levels, CAN input). That is the firmware's whole view of
the world, so replay starts the firmware against a small server that answers each request
with the logged reply, without any simulator, and compares what the firmware sends with
what it sent then. Identical firmware gives identical bytes; a changed parameter shows
up as the first message that differs.

Onto a CAN bus: the ``/can/raw`` frames are sent through python-can with their logged
spacing (scaled by ``rate``).
"""
from __future__ import annotations

import json
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterable

from hexhil.hil import scenario as scenario_mod
from hexhil.hil.scenario import check_span
from hexhil.hil.scenario.rules import within
from hexhil.dynamixel.decode import DECODERS
from hexhil.replay_result import Divergence, ReplayResult
from hexhil.protocol import sim_link
from hexhil.protocol.dynamixel import models
from hexhil.hil.link.served_firmware import (BOARD_RUNTIME, EXECUTABLE, ElfFirmware, console_events,
                                      served_firmware)
from hexhil.hil.mcu.flash_fs import FlashFiles
from hexhil.hil.mcu.replayed import ReplayedElf
from hexhil import log_replay
from hexhil.hil.link.firmware_child import FirmwareProcess
from hexhil.hil.link.firmware_process import REQUEST_OPS, split_messages
from hexhil.trace.protobuf import CanFrame, LinkExchanges
from hexhil.trace.reader import Trace
from hexhil.trace.topics import T_CAN_RAW, T_LINK
from hexhil.protocol.errors import BadFile, BadValue, UserError

if TYPE_CHECKING:
    import can

IMPORTED = "trace import"   # host_tools/trace/import_logs.py SOURCE: a robot's own log
# What each link message is, for reports and --topics.
OP_TOPICS = {sim_link.OP_HELLO: "hello", sim_link.OP_TRANSACT: "uart", sim_link.OP_WRITE: "uart",
             sim_link.OP_SLEEP: "sleep", sim_link.OP_MORE: "sleep", sim_link.OP_CAN: "can",
             sim_link.OP_EVENT: "event", sim_link.OP_LINE: "uart",
             sim_link.OP_DIRECTION: "uart", sim_link.OP_READS: "uart",
             sim_link.OP_EVENT_AT: "event"}
TOPICS = ("uart", "can", "sleep", "event", "hello")
MAX_RATE = 1e6   # wall-clock pacing: a million times real time is as good as none
# Events whose text is not a firmware output: wall-clock profiling counters.
UNCOMPARED_EVENTS = (sim_link.EVENT_STATS,)
# Events whose text is a JSON object: compared decoded, because MicroPython's dicts do not
# keep insertion order and its json writes the keys in another order than CPython's, so a
# trace of one runtime replays under the other.
JSON_EVENTS = (sim_link.EVENT_TACTILE, sim_link.EVENT_FAULT)


def _compared(op: int, payload: bytes) -> bool:
    if op == sim_link.OP_HELLO:
        return False  # names the runtime, which --runtime may change on purpose
    return _event_kind(op, payload) not in UNCOMPARED_EVENTS


def _event_kind(op: int, payload: bytes) -> int | None:
    """An event's kind (E, or T after its time), None for any other message."""
    if op == sim_link.OP_EVENT and payload:
        return payload[0]
    if op == sim_link.OP_EVENT_AT and len(payload) >= sim_link.EVENT_AT_HEAD_LEN:
        return payload[sim_link.EVENT_AT_HEAD_LEN - 1]
    return None


def _same(e: tuple[int, bytes] | None, a: tuple[int, bytes] | None) -> bool:
    if e == a:
        return True
    if e is None or a is None or e[0] != sim_link.OP_EVENT or a[0] != sim_link.OP_EVENT:
        return False
    if not e[1] or e[1][:1] != a[1][:1] or e[1][0] not in JSON_EVENTS:
        return False
    try:
        return json.loads(e[1][1:]) == json.loads(a[1][1:])
    except ValueError:
        return False


def _describe(op: int, payload: bytes) -> str:
    return "%s %s" % (chr(op) if 32 < op < 127 else "0x%02X" % op, payload.hex())


def uart_bytes(op: int, payload: bytes) -> bytes | None:
    """The servo-line bytes a link message carries (protocol/sim_link.py: a transact's, a
    line request's, a posted write's, the packets of a version 2 reads request, in order)."""
    if op == sim_link.OP_READS:
        out, at = bytearray(), 1
        for _ in range(payload[0] if payload else 0):
            at += sim_link.READ_HEAD_LEN
            if at >= len(payload):
                break
            n = payload[at]
            out += payload[at + 1:at + 1 + n]
            at += 1 + n
        return bytes(out)
    skip = {sim_link.OP_TRANSACT: 6, sim_link.OP_LINE: 11, sim_link.OP_WRITE: 0}.get(op)
    return None if skip is None else payload[skip:]


def _decoded(div: Divergence, expected: list[tuple[int, bytes]],
             actual: list[tuple[int, bytes]], model: str) -> None:
    """Name the packets of a divergence on the servo line (``Divergence.packets``): each
    with its parameters read against the model's control table."""
    if div.topic != "uart":
        return
    names, table = DECODERS[models.protocol(model)].names, models.table(model)
    div.packets = {side: [n for op, p in msgs if (b := uart_bytes(op, p))
                          for n in names(b, table)]
                   for side, msgs in (("expected", expected), ("actual", actual))}


def trace_model(trace: Trace) -> str:
    """The servo model of the trace's scenario (in the metadata); the default model
    (AX-12, Protocol 1.0) for a trace that does not carry its scenario."""
    data = trace.metadata().get("scenario_data")
    try:
        return scenario_mod.parse(json.loads(data)).bus.model if data else models.DEFAULT
    except (ValueError, UserError):
        return models.DEFAULT


def load_exchanges(trace: Trace, start_s: float | None = None, end_s: float | None = None
                   ) -> list[tuple[int, bytes, bytes]]:
    """(t_us, request, reply) of every logged link exchange, in order."""
    if T_LINK not in trace.topics():
        raise BadValue(f"{trace.path}: no {T_LINK} topic: this trace holds no "
                       "firmware link exchanges to replay (a recorded firmware run's trace has them)")
    cls = LinkExchanges
    schemas = {trace.schemas[c.schema_id].name for c in trace.channels.values()
               if c.topic == T_LINK and c.schema_id in trace.schemas}
    if schemas != {cls.DESCRIPTOR.full_name}:
        got = ", ".join(sorted(schemas)) or "untyped"
        raise BadValue(f"{trace.path}: {T_LINK} is {got}, not "
                       f"{cls.DESCRIPTOR.full_name}: recorded by another hexhil version; "
                       "record it again with this one")
    out = []
    for m in trace.messages([T_LINK], None, end_s):
        try:
            batch = cls.FromString(m.data).exchanges
        except Exception:
            raise BadValue(f"{trace.path}: corrupt {T_LINK} message at "
                           f"t={m.log_time_ns / 1e9:.6f} s") from None
        end_us = None if end_s is None else end_s * 1e6
        out.extend((x.t_us, x.request, x.reply) for x in batch
                   if end_us is None or x.t_us < end_us)
    return out


def replay_firmware(path: str | Path, python: str = "micropython", rate: float = 0.0,
                    start_s: float | None = None, end_s: float | None = None,
                    topics: Iterable[str] | None = None, timeout_s: float = 60.0,
                    command: list[str] | None = None, firmware: str | None = None,
                    scenario: str | Path | None = None,
                    flash_files: FlashFiles | None = None) -> ReplayResult:
    """Serve the logged replies to a fresh firmware process and compare its messages.

    ``start_s``/``end_s`` bound the compared stretch (the firmware always boots from t=0,
    so replay runs from the start and stops at ``end_s``); ``topics`` limits the
    comparison to some of ``TOPICS``; ``rate`` > 0 paces replies in wall time (1.0 =
    real time), 0 runs as fast as the firmware goes. ``firmware`` is the one the trace was
    recorded with (``hexhil run --firmware``'s: a main file for the virtual board or an
    executable); ``flash_files`` the /flash a MicroPython ELF was run with (``--main``,
    ``--fs``), its ``out`` where that /flash goes after the replay (``--fs-out``). A robot's imported log (``hexhil trace import``) replays through
    host_tools/log_replay.py, its firmware settings those of ``scenario`` if given.
    """
    if python not in ("micropython", "cpython"):
        raise BadValue(f"python must be micropython or cpython, not {python!r}",
                       params=("python",))
    within("rate (0: as fast as possible)", rate, 0.0, MAX_RATE, params=("rate",))
    check_span(start_s, end_s)
    wanted = set(TOPICS)
    if topics:
        wanted = {t for item in topics for t in item.split(",") if t}
        bad = sorted(wanted - set(TOPICS))
        if bad:
            raise BadValue(f"unknown replay topic(s) {', '.join(bad)} "
                           f"(known: {', '.join(TOPICS)})")
    with Trace(path) as tr:
        imported = tr.metadata().get("source") == IMPORTED
        recorded_with = tr.metadata().get("firmware_runtime")
        if firmware is None and recorded_with in (BOARD_RUNTIME, EXECUTABLE):
            _needs_firmware(path, recorded_with, tr.metadata())
        exchanges = [] if imported else load_exchanges(tr, start_s, end_s)
        model = trace_model(tr)
    if imported:   # a robot's own log: the firmware becomes the logged line's master
        if start_s is not None or end_s is not None or topics or rate:
            raise UserError(f"{path} is a robot's log (hexhil trace import): it replays whole, "
                            "without start_s, end_s, topics or rate",
                            params=("start_s", "end_s", "topics", "rate"))
        return log_replay.replay_log(path, python, scenario, firmware, timeout_s)
    if scenario is not None:
        raise UserError(f"{path}: scenario is for a robot's imported log; a recorded run "
                        "replays with its own settings", params=("scenario",))
    if not exchanges:
        raise UserError(f"{path}: the {T_LINK} topic is empty in the chosen time range")
    start_us = int(round((start_s or 0.0) * 1e6))
    if exchanges[-1][0] < start_us:   # nothing would be compared: not "identical"
        raise BadValue(f"start_s {start_s:g}: {path}'s link exchanges end at "
                       f"{exchanges[-1][0] * 1e-6:.3f} s: nothing to compare from there",
                       params=("start_s",))

    result = ReplayResult()
    wall0 = time.perf_counter()
    theirs = (served_firmware(firmware, flash_files=flash_files) if firmware is not None
              else None)
    if isinstance(theirs, ElfFirmware):      # runs in this process, on a thread
        fw: Any = ReplayedElf(theirs.image, console_events, theirs.fs_image,
                              flash_files.out if flash_files is not None else None)
    else:
        fw = FirmwareProcess(python, connect_timeout_s=timeout_s,
                             command=theirs.command() if theirs else command,
                             extra_env=theirs.env() if theirs else None)
    try:
        conn = fw.conn
        prev_t_us = 0
        for i, (t_us, request, reply) in enumerate(exchanges):
            try:
                expected = split_messages(request)
            except ValueError as exc:
                raise BadValue(f"{path}: corrupt {T_LINK} exchange {i}: {exc}") from None
            actual, closed = conn.batch()
            div = _compare(expected, actual, wanted, prev_t_us, i,
                           compare=prev_t_us >= start_us)
            if div is not None:
                _decoded(div, expected, actual, model)
                result.divergence = div
                result.identical = False
                break
            if prev_t_us >= start_us:
                result.compared_messages += sum(1 for op, p in expected if _compared(op, p)
                                                and OP_TOPICS.get(op, "?") in wanted)
            result.exchanges = i + 1
            if closed or not reply:
                break
            if rate > 0:
                lag = wall0 + t_us * 1e-6 / rate - time.perf_counter()
                if lag > 0:
                    time.sleep(lag)
            try:
                conn.sock.sendall(reply)
            except OSError:
                break  # the firmware went away; the next comparison has already been made
            prev_t_us = t_us
    finally:
        if result.divergence is not None or end_s is not None:
            fw.kill()  # stopped early on purpose: the firmware waits for a reply
            result.firmware_exit = fw.proc.returncode
        else:
            code, _, err = fw.finish(timeout_s=10.0)
            result.firmware_exit = code
            result.stderr_tail = err[-2000:]
    result.extra["wall_s"] = time.perf_counter() - wall0
    return result


def _needs_firmware(path: str | Path, runtime: str, metadata: dict[str, str]) -> None:
    """A trace of a firmware of the user's replays into that firmware only: say so."""
    try:
        recorded = json.loads(metadata.get("overrides", "{}")).get("firmware")
    except ValueError:
        recorded = None
    was = f" ({recorded})" if recorded else ""
    raise UserError(f"{path} was recorded with firmware{was}, runtime {runtime}: give the "
                    "same PATH to replay it", params=("firmware",))


def _compare(expected: list[tuple[int, bytes]], actual: list[tuple[int, bytes]],
             wanted: set[str], t_us: int, index: int, compare: bool) -> Divergence | None:
    """First differing compared message of one exchange, or None."""
    exp = [(op, p) for op, p in expected if _compared(op, p)
           and OP_TOPICS.get(op, "?") in wanted]
    act = [(op, p) for op, p in actual if _compared(op, p)
           and OP_TOPICS.get(op, "?") in wanted]
    # Requests must line up even when their topic is not compared, or replies would
    # go to the wrong question.
    exp_req = [op for op, _ in expected if op in REQUEST_OPS]
    act_req = [op for op, _ in actual if op in REQUEST_OPS]
    if compare:
        for k in range(max(len(exp), len(act))):
            e = exp[k] if k < len(exp) else None
            a = act[k] if k < len(act) else None
            if not _same(e, a):
                op = (e or a)[0]
                return Divergence(t_us / 1e6, OP_TOPICS.get(op, "?"),
                                  _describe(*e) if e else "(nothing)",
                                  _describe(*a) if a else "(nothing: firmware stopped)",
                                  index)
    if exp_req != act_req:
        op = (exp_req or act_req)[0]
        e = next(((o, p) for o, p in expected if o in REQUEST_OPS), None)
        a = next(((o, p) for o, p in actual if o in REQUEST_OPS), None)
        return Divergence(t_us / 1e6, OP_TOPICS.get(op, "?"),
                          _describe(*e) if e else "(nothing)",
                          _describe(*a) if a else "(nothing: firmware stopped)", index)
    return None


# -- onto a CAN bus -----------------------------------------------------------------------
def parse_can_target(spec: str) -> tuple[str, str]:
    interface, sep, channel = spec.partition(":")
    if not sep or not interface or not channel:
        raise BadValue(f"spec wants INTERFACE:CHANNEL (e.g. virtual:0, "
                       f"socketcand:hexhil0), got {spec!r}", params=("spec",))
    return interface, channel


def _bus_kwargs(items: Iterable[str]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for item in items or ():
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise BadValue(f"bus_args wants KEY=VALUE, got {item!r}", params=("bus_args",))
        try:
            out[key] = int(value)
        except ValueError:
            out[key] = value
    return out


def replay_can(path: str | Path, spec: str, rate: float = 1.0, start_s: float | None = None,
               end_s: float | None = None, bus_args: Iterable[str] = (),
               bus: can.BusABC | None = None, sleep: Callable[[float], None] = time.sleep) -> dict[str, Any]:
    """Send the logged ``/can/raw`` frames through python-can, keeping their spacing
    (divided by ``rate``; 0 sends back to back)."""
    import can

    within("rate (0: back to back)", rate, 0.0, MAX_RATE, params=("rate",))
    check_span(start_s, end_s)
    interface, channel = parse_can_target(spec)
    cls = CanFrame
    with Trace(path) as tr:
        if T_CAN_RAW not in tr.topics():
            raise BadValue(f"{tr.path}: no CAN frames to replay (no {T_CAN_RAW} topic)")
        frames = [(m.log_time_ns, cls.FromString(m.data))
                  for m in tr.messages([T_CAN_RAW], start_s, end_s)]
    if not frames:
        raise UserError(f"{path}: no CAN frames in the chosen time range",
                        params=("start_s", "end_s"))
    own = bus is None
    if own:
        try:
            bus = can.Bus(interface=interface, channel=channel, **_bus_kwargs(bus_args))
        except Exception as exc:  # python-can raises many kinds for a bad interface
            why = str(exc).splitlines()[0] if str(exc) else exc.__class__.__name__
            raise BadFile(f"cannot open CAN {spec}: {why}") from None
    sent = 0
    wall0 = time.perf_counter()
    t0_ns = frames[0][0] if frames else 0
    try:
        for log_ns, f in frames:
            if rate > 0:
                lag = wall0 + (log_ns - t0_ns) * 1e-9 / rate - time.perf_counter()
                if lag > 0:
                    sleep(lag)
            bus.send(can.Message(arbitration_id=f.arbitration_id, data=f.data,
                                 is_extended_id=f.is_extended_id,
                                 timestamp=log_ns / 1e9))
            sent += 1
    except can.CanError as exc:
        raise UserError(f"CAN {spec}: send failed after {sent} frames ({exc})") from None
    finally:
        if own:
            bus.shutdown()
    return {"target": spec, "frames": sent, "wall_s": time.perf_counter() - wall0,
            "span_s": (frames[-1][0] - t0_ns) / 1e9 if frames else 0.0}
