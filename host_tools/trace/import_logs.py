"""A real robot's logs -> a trace in our schemas (``hexhil trace import``), its times on the
virtual clock: each log's first record at t = 0, plus its map section's ``offset_s``. One
log of each kind of one session (a capture of the servo line and the CAN log of the same
run, say) make one trace, their records written in time order.

Three kinds (``LogKind``), told apart by the file's name unless ``kind`` says:

* ``can``: a CAN log python-can's ``LogReader`` reads (``.asc``, ``.blf``, ``.log``
  candump -L, ``.csv``, ``.trc``, ``.db``; ``.mf4`` with its asammdf) -> ``/can/raw`` and
  the DBC's decoded frames. A frame is the firmware's (``tx``) when the map's ``[can] tx_ids`` lists its ID,
  else as the log marks it (python-can's ``is_rx``).
* ``serial``: a logic analyser's capture of the servo line (sigrok ``.sr``) -> ``/serial``,
  decoded as half-duplex Dynamixel traffic (host_tools/trace/servo_capture.py); the map's
  ``[serial]`` names the channels, baud and protocol where the capture cannot say.
* ``rosbag2``: a ROS 2 bag (its folder, or its ``metadata.yaml``), read with ``rosbags``
  (sqlite3 or MCAP storage, CDR); the map's ``[topics."/name"]`` tables say what each topic
  is (``host_tools/trace/rosbag_import.py``).

Every import is checked: a truncated or unreadable log, a capture whose sample rate fits
no baud, a topic the bag lacks are one-line ``UserError``s, and the partial trace is
removed (host_tools/trace/target.py).
"""
from __future__ import annotations

import json
import tomllib
from enum import Enum
from pathlib import Path
from typing import Any

from hexhil.hil.scenario.sections import MAX_DURATION_S
from hexhil.trace.reader import why
from hexhil.trace.recorder import Recorder
from hexhil.trace.windows import EncodeIn
from hexhil.trace.servo_capture import LineMap, ServoLine, decode_line
from hexhil.protocol.dynamixel import models
from hexhil.protocol.errors import BadFile, BadValue, UserError

SOURCE = "trace import"   # the metadata's ``source``: replay and conformance look for it


class LogKind(str, Enum):
    CAN = "can"
    SERIAL = "serial"
    ROSBAG2 = "rosbag2"


CAN_SUFFIXES = (".asc", ".blf", ".log", ".csv", ".trc", ".mf4", ".db")
TEXT_SUFFIXES = (".asc", ".log", ".csv", ".trc")
SERIAL_SUFFIXES = (".sr",)
MAP_SECTIONS = ("serial", "can", "rosbag2", "topics")


def guess_kind(src: Path) -> LogKind:
    """The kind a file's name says (a folder or ``metadata.yaml`` is a rosbag2)."""
    suffix = src.suffix.lower()
    if src.is_dir() or src.name == "metadata.yaml":
        return LogKind.ROSBAG2
    if suffix in SERIAL_SUFFIXES:
        return LogKind.SERIAL
    if suffix in CAN_SUFFIXES:
        return LogKind.CAN
    if suffix in (".mcap", ".db3"):
        raise UserError(f"{src}: a rosbag2 is read from its folder (with metadata.yaml), not "
                        "its storage file; or give kind to say what the file is",
                        params=("kind",))
    raise UserError(f"{src}: cannot tell what log this is from its name: give kind can, "
                    f"serial or rosbag2 (CAN logs: {' '.join(CAN_SUFFIXES)}; captures: .sr)",
                    params=("kind",))


def load_map(path: str | Path | None) -> dict[str, Any]:
    """The mapping file (TOML), checked for its sections; {} without one."""
    if path is None:
        return {}
    p = Path(path)
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise BadFile(f"{p}: no such map file") from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise BadValue(f"{p}: not a readable TOML map ({why(exc)})") from None
    bad = sorted(set(data) - set(MAP_SECTIONS))
    if bad:
        raise BadValue(f"{p}: unknown map section(s) {', '.join(bad)} "
                       f"(known: {', '.join(MAP_SECTIONS)})")
    return data


def line_map(table: dict[str, Any], where: str) -> LineMap:
    """``[serial]``: data, direction (channel names or numbers), baud, protocol (and
    ``offset_s``, which places the log on the trace's clock: not the line's business)."""
    known = ("data", "direction", "baud", "protocol", "offset_s")
    bad = sorted(set(table) - set(known))
    if bad:
        raise BadValue(f"{where}: unknown [serial] key(s) {', '.join(bad)} "
                       f"(known: {', '.join(known)})")
    for key in ("baud", "protocol"):
        if key in table and (not isinstance(table[key], int) or isinstance(table[key], bool)):
            raise BadValue(f"{where}: [serial] {key} must be an integer")
    return LineMap(*(None if table.get(k) is None else str(table[k]) for k in known[:2]),
                   table.get("baud"), table.get("protocol"))


def read_servo_line(src: str | Path, table: dict[str, Any] | None = None,
                    where: str = "map") -> ServoLine:
    """A ``.sr`` capture's servo traffic (the map's ``[serial]`` table, if any)."""
    from hexhil.trace.logic_capture import read_sr

    return decode_line(read_sr(src), line_map(table or {}, where))


class Held:
    """One log's records, held until every log is read (then written in time order, so
    logs of one session made by several recorders share one trace): the ``Recorder``
    calls an importer makes, each log's times shifted by its ``offset_s``."""

    def __init__(self, src: Path, offset_us: int = 0) -> None:
        self.src, self.offset_us = src, offset_us
        self.items: list[tuple[int, str, tuple[Any, ...]]] = []

    def _add(self, t_us: int, method: str, args: tuple[Any, ...]) -> None:
        t = int(t_us) + self.offset_us
        if not 0 <= t <= MAX_DURATION_S * 1e6:   # a trace's times (hil/scenario)
            raise BadValue(f"{self.src}: a record at {t / 1e6:.6f} s: a log spans 0 to "
                           f"{MAX_DURATION_S:g} s from its first record (a time jumped?)")
        self.items.append((t, method, args))

    def serial(self, t_us: int, direction: str, data: bytes) -> None:
        self._add(t_us, "serial", (direction, data))

    def can(self, t_us: int, arb_id: int, data: bytes, direction: str = "tx",
            is_extended_id: bool = False) -> None:
        self._add(t_us, "can", (arb_id, data, direction, is_extended_id))

    def joints(self, t_us: int, names: list[str], positions_rad: list[float],
               velocities_rad_s: list[float] | None = None,
               efforts_nm: list[float] | None = None) -> None:
        self._add(t_us, "joints", (names, positions_rad, velocities_rad_s, efforts_nm))

    def switch_edge(self, t_us: int, leg: int, level: bool) -> None:
        self._add(t_us, "switch_edge", (leg, level))


def _offset_us(table: dict[str, Any], section: str, where: str) -> int:
    value = table.get("offset_s", 0.0)
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not 0 <= value <= MAX_DURATION_S:
        raise BadValue(f"{where}: [{section}] offset_s must be a number of seconds, 0 to "
                       f"{MAX_DURATION_S:g}")
    return int(round(value * 1e6))


def _import_serial(src: Path, maps: dict[str, Any], where: str, held: Held
                   ) -> tuple[dict[str, Any], dict[str, Any]]:
    line = read_servo_line(src, maps.get("serial"), where)
    t0 = line.bursts[0].t_us
    for b in line.bursts:
        held.serial(b.t_us - t0, b.direction, b.data)
    tx = sum(1 for b in line.bursts if b.direction == "tx")
    meta = {"baud": line.baud, "protocol": line.protocol,
            "scenario_data": json.dumps({"bus": {"model": models.default_model(line.protocol),
                                                 "baud": line.baud}})}
    return meta, {"bursts": len(line.bursts), "master_bursts": tx, "baud": line.baud,
                  "protocol": line.protocol, "framing_errors": len(line.framing_errors_us),
                  "direction_channel": line.direction_channel}


def _import_can(src: Path, maps: dict[str, Any], where: str, held: Held
                ) -> tuple[dict[str, Any], dict[str, Any]]:
    import can

    table = maps.get("can", {})
    bad = sorted(set(table) - {"tx_ids", "offset_s"})
    if bad:
        raise BadValue(f"{where}: unknown [can] key(s) {', '.join(bad)} "
                       "(known: tx_ids, offset_s)")
    tx_ids = table.get("tx_ids")
    if tx_ids is not None and not (isinstance(tx_ids, list)
                                   and all(isinstance(i, int) for i in tx_ids)):
        raise BadValue(f"{where}: [can] tx_ids must be a list of integer CAN IDs")
    try:
        reader = can.LogReader(str(src))
    except FileNotFoundError:
        raise BadFile(f"{src}: no such CAN log") from None
    except Exception as exc:   # python-can raises many kinds for an unreadable log
        raise BadValue(f"{src}: not a CAN log python-can reads ({why(exc)})") from None
    frames = []
    try:
        with reader:
            for msg in reader:
                if msg.is_error_frame or msg.is_remote_frame:
                    continue
                frames.append(msg)
    except Exception as exc:
        raise BadValue(f"{src}: truncated or malformed CAN log after {len(frames)} frames "
                       f"({why(exc)})") from None
    _check_truncated(src, frames)
    if not frames:
        raise BadValue(f"{src}: the CAN log holds no data frames")
    t0 = frames[0].timestamp
    last = 0
    tx = 0
    for msg in frames:
        t_us = int(round((msg.timestamp - t0) * 1e6))
        if t_us < last:
            raise BadValue(f"{src}: frame times go backwards at {msg.timestamp:.6f} s")
        last = t_us
        sent = (msg.arbitration_id in tx_ids) if tx_ids is not None else not msg.is_rx
        tx += sent
        held.can(t_us, msg.arbitration_id, bytes(msg.data), "tx" if sent else "rx",
                 msg.is_extended_id)
    return {}, {"frames": len(frames), "firmware_frames": tx}


def _check_truncated(src: Path, frames: list) -> None:
    """A log cut short where python-can's reader stops quietly: a BLF's last object is
    partial (its header's file size is compared with the file's); an ASC lacks the
    ``End TriggerBlock`` line every writer ends it with, its last line dropped; a text log
    cut inside its last line (``120#2727`` of ``120#27272727``) has no newline at its end."""
    import struct

    suffix = src.suffix.lower()
    if suffix in TEXT_SUFFIXES:
        with open(src, "rb") as f:
            f.seek(max(0, src.stat().st_size - 1))
            if f.read(1) not in (b"\n", b""):
                raise BadValue(f"{src}: truncated log: its last line is cut short (no newline "
                               f"at the end; {len(frames)} frames read)")
    if suffix == ".asc":
        with open(src, "rb") as f:
            f.seek(max(0, src.stat().st_size - 256))
            tail = f.read().decode("ascii", errors="replace").strip().splitlines()
        if not tail or not tail[-1].strip().lower().startswith("end triggerblock"):
            raise BadValue(f"{src}: truncated ASC log: it does not end with 'End "
                           f"TriggerBlock' ({len(frames)} frames read before the end)")
        return
    if suffix != ".blf":
        return

    with open(src, "rb") as f:
        head = f.read(32)
    if len(head) < 32 or head[:4] != b"LOGG":
        raise BadValue(f"{src}: not a BLF file (no LOGG header)")
    file_size = struct.unpack_from("<Q", head, 16)[0]
    if file_size and src.stat().st_size < file_size:
        raise BadValue(f"{src}: truncated BLF log: {src.stat().st_size} of {file_size} bytes "
                       f"({len(frames)} frames read before the end)")


def import_log(src: str | Path | list[str | Path], dst: str | Path,
               kind: str | LogKind | None = None, map_path: str | Path | None = None,
               overwrite: bool = False) -> dict[str, Any]:
    """Import one log, or several of one session (a CAN log and a capture of the servo
    line, say) into one trace, each from t = 0 plus its map section's ``offset_s``; the
    module docstring says which logs. Returns what was written, a summary a log."""
    srcs = [Path(p) for p in (src if isinstance(src, list) else [src])]
    if not srcs:
        raise BadValue("no log to import")
    maps = load_map(map_path)
    where = str(map_path) if map_path is not None else "map"
    meta: dict[str, Any] = {"source": SOURCE}
    summaries = []
    held: list[Held] = []
    for path in srcs:
        if not path.exists():
            raise BadFile(f"{path}: no such log file or folder")
        try:
            k = LogKind(kind) if kind is not None else guess_kind(path)
        except ValueError:
            raise BadValue(f"unknown log kind {kind!r} (one of "
                           f"{', '.join(k.value for k in LogKind)})") from None
        if any(k.value == s["kind"] for s in summaries):
            raise BadValue(f"{path}: a second {k.value} log: give one log of each kind")
        table = maps.get(k.value, {})
        if k is LogKind.ROSBAG2 and set(table) - {"offset_s"}:
            raise BadValue(f"{where}: unknown [rosbag2] key(s) "
                           f"{', '.join(sorted(set(table) - {'offset_s'}))} (known: offset_s)")
        h = Held(path, _offset_us(table, k.value, where))
        if k is LogKind.SERIAL:
            extra, summary = _import_serial(path, maps, where, h)
        elif k is LogKind.CAN:
            extra, summary = _import_can(path, maps, where, h)
        else:
            from hexhil.trace import rosbag_import

            extra, summary = {}, rosbag_import.import_bag(path, maps, where, h)
        meta.update(extra)
        summaries.append({"input": str(path), "kind": k.value, **summary})
        held.append(h)
    meta.update(imported=",".join(s["kind"] for s in summaries),
                logs=",".join(p.name for p in srcs))
    protocol = int(meta.get("protocol", models.protocol(models.DEFAULT)))
    # everything is read before the first record is written: nothing to overlap a child with
    rec = Recorder(dst, meta, protocol=protocol, overwrite=overwrite,
                   encode_in=EncodeIn.THIS_PROCESS)
    try:
        items = sorted((item for h in held for item in h.items), key=lambda item: item[0])
        for t_us, method, args in items:
            getattr(rec, method)(t_us, *args)
    except BaseException:
        rec.discard()
        raise
    rec.close()
    out = {"output": str(dst), "logs": summaries}
    if len(summaries) == 1:
        out.update(summaries[0])
    return out
