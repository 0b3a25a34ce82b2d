"""A real robot's logs -> a trace in our schemas (``hexhil trace import``), its times on the
virtual clock (t = 0 at the log's first record).

Three kinds (``LogKind``), told apart by the file's name unless ``kind`` says:

* ``can``: a CAN log python-can's ``LogReader`` reads (``.asc``, ``.blf``, ``.log``
  candump -L, ``.csv``, ``.trc``, ``.mf4``, ``.db``) -> ``/can/raw`` and the DBC's decoded
  frames. A frame is the firmware's (``tx``) when the map's ``[can] tx_ids`` lists its ID,
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

from host_tools.trace.reader import why
from host_tools.trace.recorder import Recorder
from host_tools.trace.servo_capture import LineMap, ServoLine, decode_line
from protocol.dynamixel import models
from protocol.errors import UserError

SOURCE = "trace import"   # the metadata's ``source``: replay and conformance look for it


class LogKind(str, Enum):
    CAN = "can"
    SERIAL = "serial"
    ROSBAG2 = "rosbag2"


CAN_SUFFIXES = (".asc", ".blf", ".log", ".csv", ".trc", ".mf4", ".db")
SERIAL_SUFFIXES = (".sr",)
MAP_SECTIONS = ("serial", "can", "topics")


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
                        "its storage file; or pass --as to say what the file is")
    raise UserError(f"{src}: cannot tell what log this is from its name: pass --as can, "
                    f"serial or rosbag2 (CAN logs: {' '.join(CAN_SUFFIXES)}; captures: .sr)")


def load_map(path: str | Path | None) -> dict[str, Any]:
    """The mapping file (TOML), checked for its sections; {} without one."""
    if path is None:
        return {}
    p = Path(path)
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise UserError(f"{p}: no such map file") from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise UserError(f"{p}: not a readable TOML map ({why(exc)})") from None
    bad = sorted(set(data) - set(MAP_SECTIONS))
    if bad:
        raise UserError(f"{p}: unknown map section(s) {', '.join(bad)} "
                        f"(known: {', '.join(MAP_SECTIONS)})")
    return data


def line_map(table: dict[str, Any], where: str) -> LineMap:
    """``[serial]``: data, direction (channel names or numbers), baud, protocol."""
    known = ("data", "direction", "baud", "protocol")
    bad = sorted(set(table) - set(known))
    if bad:
        raise UserError(f"{where}: unknown [serial] key(s) {', '.join(bad)} "
                        f"(known: {', '.join(known)})")
    for key in ("baud", "protocol"):
        if key in table and (not isinstance(table[key], int) or isinstance(table[key], bool)):
            raise UserError(f"{where}: [serial] {key} must be an integer")
    return LineMap(*(None if table.get(k) is None else str(table[k]) for k in known[:2]),
                   table.get("baud"), table.get("protocol"))


def read_servo_line(src: str | Path, table: dict[str, Any] | None = None,
                    where: str = "map") -> ServoLine:
    """A ``.sr`` capture's servo traffic (the map's ``[serial]`` table, if any)."""
    from host_tools.trace.logic_capture import read_sr

    return decode_line(read_sr(src), line_map(table or {}, where))


def _model_of(protocol: int) -> str:
    """The trace's servo model: the default one of the line's protocol."""
    return models.DEFAULT if protocol == models.protocol(models.DEFAULT) else next(
        name for name, (_, v) in models.MODELS.items() if v == protocol)


def _import_serial(src: Path, maps: dict[str, Any], where: str,
                   dst: str | Path, overwrite: bool) -> tuple[Recorder, dict[str, Any]]:
    line = read_servo_line(src, maps.get("serial"), where)
    t0 = line.bursts[0].t_us
    rec = Recorder(dst, _meta(src, LogKind.SERIAL, {
        "baud": line.baud, "protocol": line.protocol,
        "scenario_data": json.dumps({"bus": {"model": _model_of(line.protocol),
                                             "baud": line.baud}})}),
        protocol=line.protocol, overwrite=overwrite)
    for b in line.bursts:
        rec.serial(b.t_us - t0, b.direction, b.data)
    tx = sum(1 for b in line.bursts if b.direction == "tx")
    return rec, {"bursts": len(line.bursts), "master_bursts": tx, "baud": line.baud,
                 "protocol": line.protocol, "framing_errors": len(line.framing_errors_us),
                 "direction_channel": line.direction_channel}


def _import_can(src: Path, maps: dict[str, Any], where: str, dst: str | Path,
                overwrite: bool) -> tuple[Recorder, dict[str, Any]]:
    import can

    table = maps.get("can", {})
    bad = sorted(set(table) - {"tx_ids"})
    if bad:
        raise UserError(f"{where}: unknown [can] key(s) {', '.join(bad)} (known: tx_ids)")
    tx_ids = table.get("tx_ids")
    if tx_ids is not None and not (isinstance(tx_ids, list)
                                   and all(isinstance(i, int) for i in tx_ids)):
        raise UserError(f"{where}: [can] tx_ids must be a list of integer CAN IDs")
    try:
        reader = can.LogReader(str(src))
    except FileNotFoundError:
        raise UserError(f"{src}: no such CAN log") from None
    except Exception as exc:   # python-can raises many kinds for an unreadable log
        raise UserError(f"{src}: not a CAN log python-can reads ({why(exc)})") from None
    frames = []
    try:
        with reader:
            for msg in reader:
                if msg.is_error_frame or msg.is_remote_frame:
                    continue
                frames.append(msg)
    except Exception as exc:
        raise UserError(f"{src}: truncated or malformed CAN log after {len(frames)} frames "
                        f"({why(exc)})") from None
    _check_truncated(src, frames)
    if not frames:
        raise UserError(f"{src}: the CAN log holds no data frames")
    t0 = frames[0].timestamp
    rec = Recorder(dst, _meta(src, LogKind.CAN, {}), overwrite=overwrite)
    last = 0
    tx = 0
    for msg in frames:
        t_us = int(round((msg.timestamp - t0) * 1e6))
        if t_us < last:
            rec.discard()
            raise UserError(f"{src}: frame times go backwards at {msg.timestamp:.6f} s")
        last = t_us
        sent = (msg.arbitration_id in tx_ids) if tx_ids is not None else not msg.is_rx
        tx += sent
        rec.can(t_us, msg.arbitration_id, bytes(msg.data), "tx" if sent else "rx",
                msg.is_extended_id)
    return rec, {"frames": len(frames), "firmware_frames": tx}


def _check_truncated(src: Path, frames: list) -> None:
    """A binary log cut short: python-can's BLF reader stops quietly at a partial object,
    so its header's file size is compared with the file's."""
    if src.suffix.lower() != ".blf":
        return
    import struct

    with open(src, "rb") as f:
        head = f.read(32)
    if len(head) < 32 or head[:4] != b"LOGG":
        raise UserError(f"{src}: not a BLF file (no LOGG header)")
    file_size = struct.unpack_from("<Q", head, 16)[0]
    if file_size and src.stat().st_size < file_size:
        raise UserError(f"{src}: truncated BLF log: {src.stat().st_size} of {file_size} bytes "
                        f"({len(frames)} frames read before the end)")


def _meta(src: Path, kind: LogKind, extra: dict[str, Any]) -> dict[str, Any]:
    return {"source": SOURCE, "imported": kind.value, "log": src.name, **extra}


def import_log(src: str | Path, dst: str | Path, kind: str | LogKind | None = None,
               map_path: str | Path | None = None, overwrite: bool = False) -> dict[str, Any]:
    """Import one log (the module docstring says which); returns what was written."""
    src = Path(src)
    if not src.exists():
        raise UserError(f"{src}: no such log file or folder")
    try:
        k = LogKind(kind) if kind is not None else guess_kind(src)
    except ValueError:
        raise UserError(f"unknown log kind {kind!r} (one of "
                        f"{', '.join(k.value for k in LogKind)})") from None
    maps = load_map(map_path)
    where = str(map_path) if map_path is not None else "map"
    if k is LogKind.SERIAL:
        rec, summary = _import_serial(src, maps, where, dst, overwrite)
    elif k is LogKind.CAN:
        rec, summary = _import_can(src, maps, where, dst, overwrite)
    else:
        from host_tools.trace import rosbag_import

        rec, summary = rosbag_import.import_bag(src, maps, where, dst, overwrite,
                                                _meta(src, k, {}))
    rec.close()
    return {"input": str(src), "output": str(dst), "kind": k.value, **summary}
