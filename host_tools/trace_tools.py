"""Reading our MCAP traces: open with one-line errors, filter, decode, summarise, export,
recover an unfinished file, and import a physical robot's CSV log.

Every function that takes a trace path raises ``UserError`` (one line, exit 2) for a
missing, non-MCAP, truncated or corrupt file, never a traceback: the trace tools are
what a user points at whatever file is lying around after a crash.
"""
from __future__ import annotations

import csv
import fnmatch
import io
import json
import math
import struct
import zlib
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, NamedTuple

import zstandard
from mcap.reader import SeekingReader
from mcap.records import (Attachment, Channel, Chunk, Footer, Header, Message, Metadata,
                          Schema)
from mcap.stream_reader import StreamReader, breakup_chunk, get_chunk_data_stream
from mcap.writer import CompressionType, Writer
from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoderFactory

from host_tools import recorder as rec
from protocol.errors import UserError

MAGIC = b"\x89MCAP0\r\n"
_OP_CHUNK = 0x06    # MCAP record opcodes (mcap.opcode)
_OP_MESSAGE = 0x05


class TraceMessage(NamedTuple):
    topic: str
    log_time_ns: int
    schema_name: str
    data: bytes
    channel_id: int


def _check_file(path: Path) -> None:
    if not path.exists():
        raise UserError(f"{path}: no such trace file")
    if path.is_dir():
        raise UserError(f"{path}: is a directory, not a trace file")
    try:
        with open(path, "rb") as f:
            head = f.read(len(MAGIC))
    except OSError as exc:
        raise UserError(f"{path}: cannot read ({exc.strerror})") from None
    if head != MAGIC:
        what = "empty file" if not head else "no MCAP magic at the start"
        raise UserError(f"{path}: not an MCAP file ({what})")


def _why(exc: BaseException) -> str:
    text = str(exc).splitlines()[0] if str(exc) else ""
    return f"{exc.__class__.__name__}: {text}" if text else exc.__class__.__name__


class Trace:
    """An MCAP file opened for reading with its summary (a finished file is required)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        _check_file(self.path)
        self._f = open(self.path, "rb")
        try:
            self.reader = SeekingReader(self._f, validate_crcs=True)
            self.summary = self.reader.get_summary()
            self.header = self.reader.get_header()
        except Exception as exc:  # truncated: no footer/summary; corrupt: bad records
            self._f.close()
            raise UserError(f"{self.path}: truncated or corrupt MCAP ({_why(exc)}); "
                            f"try 'hexhil trace recover {self.path} OUT.mcap'") from None
        if self.summary is None or self.summary.statistics is None:
            self._f.close()
            raise UserError(f"{self.path}: MCAP has no summary (unfinished write); "
                            f"try 'hexhil trace recover {self.path} OUT.mcap'")
        self.channels = self.summary.channels
        self.schemas = self.summary.schemas
        self.file_order_is_time_order = self._file_order_is_time_order()

    def _file_order_is_time_order(self) -> bool:
        """True when reading in file order already gives log-time order: our recorder sorts
        each chunk, so non-overlapping chunks suffice (1.5x faster than merging)."""
        if not self.header.library.startswith("hexhil "):
            return False
        last = -1
        for ci in sorted(self.summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
            if ci.message_start_time < last:
                return False
            last = ci.message_end_time
        return True

    def close(self) -> None:
        self._f.close()

    def __enter__(self) -> "Trace":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # -- selection ------------------------------------------------------------------------
    def topics(self) -> list[str]:
        return sorted({c.topic for c in self.channels.values()})

    def select_topics(self, patterns: Iterable[str] | None) -> list[str] | None:
        """Topics matching any pattern (exact name or glob such as ``/can/*``); None = all."""
        if not patterns:
            return None
        pats = [p for item in patterns for p in item.split(",") if p]
        known = self.topics()
        out = [t for t in known if any(fnmatch.fnmatchcase(t, p) for p in pats)]
        unmatched = [p for p in pats if not any(fnmatch.fnmatchcase(t, p) for t in known)]
        if unmatched:
            raise UserError(f"{self.path}: no topic matches {', '.join(unmatched)} "
                            f"(topics: {', '.join(known)})")
        return out

    def messages(self, topics: Iterable[str] | None = None, start_s: float | None = None,
                 end_s: float | None = None, log_time_order: bool = True
                 ) -> Iterator[TraceMessage]:
        """Raw messages in log-time order; ``start_s`` inclusive, ``end_s`` exclusive."""
        sel = self.select_topics(topics)
        start_ns = None if start_s is None else max(0, int(round(start_s * 1e9)))
        end_ns = None if end_s is None else max(0, int(round(end_s * 1e9)))
        if start_ns is not None and end_ns is not None and start_ns > end_ns:
            raise UserError(f"--start ({start_s:g} s) is after --end ({end_s:g} s)")
        if self.file_order_is_time_order or not log_time_order:
            yield from self._chunk_messages(sel, start_ns, end_ns)
            return
        it = self.reader.iter_messages(topics=sel, starting_at=start_ns, ending_before=end_ns,
                                       log_time_order=True)
        message = None
        try:
            for schema, channel, message in it:
                yield TraceMessage(channel.topic, message.log_time,
                                   schema.name if schema is not None else "",
                                   message.data, channel.id)
        except UserError:
            raise
        except Exception as exc:
            last_ns = message.log_time if message is not None else 0
            raise UserError(f"{self.path}: corrupt MCAP after t={last_ns / 1e9:.6f} s "
                            f"({_why(exc)})") from None

    def _chunk_messages(self, topics: list[str] | None, start_ns: int | None,
                        end_ns: int | None) -> Iterator[TraceMessage]:
        """Messages in file order, parsed straight from the chunks (about twice the mcap
        reader's rate: the read/replay rate is a benchmark of this project)."""
        want = {cid: (ch.topic, self.schemas[ch.schema_id].name
                      if ch.schema_id in self.schemas else "")
                for cid, ch in self.channels.items() if topics is None or ch.topic in topics}
        lo = start_ns if start_ns is not None else 0
        hi = end_ns if end_ns is not None else 1 << 64
        unpack = struct.unpack_from
        dctx = zstandard.ZstdDecompressor()
        f = self._f
        for ci in sorted(self.summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
            if ci.message_end_time < lo or ci.message_start_time >= hi:
                continue
            if ci.message_index_offsets and not any(c in want for c in ci.message_index_offsets):
                continue
            try:
                f.seek(ci.chunk_start_offset)
                head = f.read(9)
                if head[0] != _OP_CHUNK:
                    raise ValueError("chunk index points at opcode 0x%02X" % head[0])
                body = f.read(unpack("<Q", head, 1)[0])
                _, _, usize, crc, clen = unpack("<QQQII", body, 0)
                comp = body[32:32 + clen].decode()
                k = 32 + clen
                rlen = unpack("<Q", body, k)[0]
                raw = body[k + 8:k + 8 + rlen]
                if comp == "zstd":
                    raw = dctx.decompress(raw, max_output_size=usize)
                elif comp:
                    raise ValueError(f"unsupported chunk compression {comp!r}")
                if len(raw) != usize or (crc and zlib.crc32(raw) != crc):
                    raise ValueError("chunk CRC or size mismatch")
            except UserError:
                raise
            except Exception as exc:
                raise UserError(f"{self.path}: corrupt chunk at byte {ci.chunk_start_offset} "
                                f"({_why(exc)})") from None
            i, n = 0, len(raw)
            while i < n:
                op = raw[i]
                length = unpack("<Q", raw, i + 1)[0]
                b = i + 9
                if op == _OP_MESSAGE:
                    cid, _, t = unpack("<HIQ", raw, b)
                    w = want.get(cid)
                    if w is not None and lo <= t < hi:
                        yield TraceMessage(w[0], t, w[1], raw[b + 22:b + length], cid)
                i = b + length

    def verify(self) -> None:
        """Decompress every chunk and check its CRC (the summary alone hides damage)."""
        try:
            with open(self.path, "rb") as f:
                for record in StreamReader(f, emit_chunks=True, validate_crcs=True).records:
                    if isinstance(record, Chunk):
                        get_chunk_data_stream(record, validate_crc=True)
        except Exception as exc:
            raise UserError(f"{self.path}: corrupt MCAP ({_why(exc)})") from None

    def metadata(self) -> dict[str, str]:
        out: dict[str, str] = {}
        try:
            for m in self.reader.iter_metadata():
                out.update(m.metadata)
        except Exception as exc:
            raise UserError(f"{self.path}: corrupt metadata ({_why(exc)})") from None
        return out

    # -- decoding -------------------------------------------------------------------------
    def decoder(self, channel_id: int) -> Callable[[bytes], Any]:
        """bytes -> dict for a channel (protobuf via its own schema, json as is)."""
        ch = self.channels[channel_id]
        schema = self.schemas.get(ch.schema_id)
        if ch.message_encoding == "protobuf" and schema is not None:
            try:
                decode = ProtobufDecoderFactory().decoder_for("protobuf", schema)
            except Exception as exc:
                raise UserError(f"{self.path}: schema {schema.name!r} is not valid protobuf "
                                f"({_why(exc)})") from None
            if decode is None:
                raise UserError(f"{self.path}: cannot decode schema {schema.name!r}")
            return lambda data: proto_to_dict(decode(data))
        if ch.message_encoding == "json":
            return json.loads
        return lambda data: {"data": bytes(data).hex()}

    def decoded(self, topics: Iterable[str] | None = None, start_s: float | None = None,
                end_s: float | None = None) -> Iterator[tuple[TraceMessage, dict[str, Any]]]:
        decoders: dict[int, Callable[[bytes], Any]] = {}
        for m in self.messages(topics, start_s, end_s):
            dec = decoders.get(m.channel_id)
            if dec is None:
                dec = decoders[m.channel_id] = self.decoder(m.channel_id)
            try:
                value = dec(m.data)
            except Exception as exc:
                raise UserError(f"{self.path}: message on {m.topic} at "
                                f"t={m.log_time_ns / 1e9:.6f} s does not decode "
                                f"({_why(exc)})") from None
            yield m, value


def proto_to_dict(msg: Any) -> dict[str, Any]:
    """Every field of a protobuf message (defaults included), bytes as hex."""
    out: dict[str, Any] = {}
    for fd in msg.DESCRIPTOR.fields:
        v = getattr(msg, fd.name)
        if fd.message_type is not None:
            if fd.is_repeated:
                v = [proto_to_dict(x) for x in v]
            elif fd.message_type.full_name == "google.protobuf.Timestamp":
                v = v.seconds + v.nanos * 1e-9
            else:
                v = proto_to_dict(v)
        elif fd.is_repeated:
            v = list(v)
        elif isinstance(v, bytes):
            v = v.hex()
        out[fd.name] = v
    return out


def open_trace(path: str | Path) -> Trace:
    return Trace(path)


# -- info ---------------------------------------------------------------------------------
def info(path: str | Path) -> dict[str, Any]:
    with Trace(path) as tr:
        tr.verify()
        st = tr.summary.statistics
        topics = []
        for ch in sorted(tr.channels.values(), key=lambda c: c.topic):
            schema = tr.schemas.get(ch.schema_id)
            topics.append({"topic": ch.topic, "messages": st.channel_message_counts.get(ch.id, 0),
                           "schema": schema.name if schema else "",
                           "schema_encoding": schema.encoding if schema else "",
                           "message_encoding": ch.message_encoding})
        start_s = st.message_start_time / 1e9 if st.message_count else 0.0
        end_s = st.message_end_time / 1e9 if st.message_count else 0.0
        comp = sorted({ci.compression or "none" for ci in tr.summary.chunk_indexes})
        return {"file": str(tr.path), "library": tr.header.library, "profile": tr.header.profile,
                "messages": st.message_count, "chunks": st.chunk_count,
                "compression": comp, "start_s": start_s, "end_s": end_s,
                "duration_s": end_s - start_s, "topics": topics, "metadata": tr.metadata()}


# -- export -------------------------------------------------------------------------------
CAN_LOG_SUFFIXES = (".asc", ".blf", ".log", ".trc")


def _flatten(prefix: str, value: Any, out: dict[str, Any]) -> None:
    if isinstance(value, dict):
        for k, v in value.items():
            _flatten(f"{prefix}.{k}" if prefix else k, v, out)
    elif isinstance(value, list) and value and isinstance(value[0], dict):
        for i, v in enumerate(value):
            _flatten(f"{prefix}[{i}]", v, out)
    elif isinstance(value, list):
        out[prefix] = " ".join(str(x) for x in value)
    else:
        out[prefix] = value


def export(path: str | Path, out: str | Path, topics: Iterable[str] | None = None,
           start_s: float | None = None, end_s: float | None = None) -> dict[str, Any]:
    """CSV (one wide table per topic) or, by suffix, a python-can CAN log of /can/raw."""
    out = Path(out)
    suffix = out.suffix.lower()
    if suffix in CAN_LOG_SUFFIXES:
        return _export_can(path, out, start_s, end_s)
    if suffix != ".csv" and out.suffix:
        raise UserError(f"{out}: unknown export format '{out.suffix}' "
                        f"(use .csv or one of {', '.join(CAN_LOG_SUFFIXES)})")
    with Trace(path) as tr:
        rows: dict[str, list[dict[str, Any]]] = {}
        for m, value in tr.decoded(topics, start_s, end_s):
            flat: dict[str, Any] = {"time_s": f"{m.log_time_ns / 1e9:.6f}"}
            _flatten("", value, flat)
            rows.setdefault(m.topic, []).append(flat)
    files = []
    if suffix == ".csv" and len(rows) <= 1:
        targets = {t: out for t in rows}
        if not rows:
            out.write_text("time_s\n")
            files.append(str(out))
    else:
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise UserError(f"{out}: cannot create export directory ({exc.strerror})") from None
        targets = {t: out / (t.strip("/").replace("/", "_") + ".csv") for t in rows}
    for topic, target in targets.items():
        cols: dict[str, None] = {}
        for r in rows[topic]:
            for k in r:
                cols.setdefault(k, None)
        try:
            with open(target, "w", newline="") as f:
                w = csv.DictWriter(f, fieldnames=list(cols))
                w.writeheader()
                w.writerows(rows[topic])
        except OSError as exc:
            raise UserError(f"{target}: cannot write ({exc.strerror})") from None
        files.append(str(target))
    return {"format": "csv", "files": files,
            "messages": sum(len(v) for v in rows.values()), "topics": sorted(rows)}


def _export_can(path: str | Path, out: Path, start_s: float | None,
                end_s: float | None) -> dict[str, Any]:
    import can

    with Trace(path) as tr:
        if rec.T_CAN_RAW not in tr.topics():
            raise UserError(f"{tr.path}: no CAN frames to export (no {rec.T_CAN_RAW} topic)")
        cls = rec.CanFrame
        n = 0
        try:
            logger = can.Logger(str(out))
        except (OSError, ValueError) as exc:
            raise UserError(f"{out}: cannot write CAN log ({_why(exc)})") from None
        with logger:
            for m in tr.messages([rec.T_CAN_RAW], start_s, end_s):
                f = cls.FromString(m.data)
                logger.on_message_received(can.Message(
                    timestamp=m.log_time_ns / 1e9, arbitration_id=f.arbitration_id,
                    is_extended_id=f.is_extended_id, data=f.data, dlc=len(f.data),
                    is_rx=f.direction != "tx", channel=0))
                n += 1
    return {"format": out.suffix.lower().lstrip("."), "files": [str(out)], "messages": n,
            "topics": [rec.T_CAN_RAW]}


# -- recover ------------------------------------------------------------------------------
_KNOWN_OPCODES = range(0x01, 0x10)


def _record_end(data: bytes, pos: int) -> int | None:
    """End offset of the top-level record at ``pos`` by its length field; None if past EOF."""
    if pos + 9 > len(data):
        return None
    end = pos + 9 + struct.unpack_from("<Q", data, pos + 1)[0]
    return end if end <= len(data) else None


def _record_at(data: bytes, pos: int) -> tuple[int, list[Any]] | None:
    """The top-level record at ``pos`` as (end offset, its records, a chunk broken up), or
    None when it is cut off, fails its CRC, or does not parse."""
    end = _record_end(data, pos)
    if end is None:
        return None
    try:
        record = next(StreamReader(io.BytesIO(data[pos:end]), skip_magic=True, emit_chunks=True,
                                   validate_crcs=True).records)
        records = breakup_chunk(record, validate_crc=True) if isinstance(record, Chunk) \
            else [record]
    except Exception:
        return None
    if isinstance(record, Chunk) and not record.uncompressed_crc:
        return None  # nothing proves an unchecked chunk is not garbage
    if not isinstance(record, Footer) and end < len(data) and data[end] not in _KNOWN_OPCODES:
        return None  # a damaged length field: what follows is not a record
    return end, records


def _next_chunk(data: bytes, pos: int) -> int | None:
    """Offset of the next chunk at or after ``pos`` that passes its CRC (resynchronising
    after damage: a chunk's CRC is what tells a record from bytes that look like one)."""
    while (pos := data.find(bytes((_OP_CHUNK,)), pos)) >= 0:
        if _record_at(data, pos) is not None:
            return pos
        pos += 1
    return None


def _salvaged_records(data: bytes) -> Iterator[Any]:
    """Every record that can be read, front to back, without the summary (a crashed writer
    leaves none). A damaged span yields ``(start, end, why)`` and reading goes on at the
    next good chunk."""
    pos = len(MAGIC)
    while pos < len(data):
        got = _record_at(data, pos)
        if got is not None:
            pos, records = got
            yield from records
            if isinstance(records[-1], Footer):
                return
            continue
        nxt = _next_chunk(data, pos + 1)
        cut = nxt is None and _record_end(data, pos) is None
        yield (pos, len(data) if nxt is None else nxt, "cut off" if cut else "damaged")
        if nxt is None:
            return
        pos = nxt


def _summary_channels(data: bytes) -> tuple[dict[int, Schema], dict[int, Channel]]:
    """Schemas and channels from the summary of a finished file, so that a damaged chunk
    that held a channel's first record loses only its own messages."""
    try:
        summary = SeekingReader(io.BytesIO(data)).get_summary()
    except Exception:
        summary = None
    if summary is None:
        return {}, {}
    return dict(summary.schemas), dict(summary.channels)


def recover(src: str | Path, dst: str | Path) -> dict[str, Any]:
    """Copy every readable message of an unfinished or damaged MCAP into a finished one.

    A crashed writer leaves a cut-off tail; a bad disk leaves a damaged chunk in the middle.
    Both are skipped and reported: reading goes on at the next chunk that passes its CRC.
    """
    src, dst = Path(src), Path(dst)
    _check_file(src)
    if dst.resolve() == src.resolve():
        raise UserError(f"{dst}: recover needs a different output file")
    try:
        data = src.read_bytes()
    except OSError as exc:
        raise UserError(f"{src}: cannot read ({exc.strerror})") from None
    try:
        out_f = open(dst, "wb")
    except OSError as exc:
        raise UserError(f"{dst}: cannot write ({exc.strerror})") from None
    schemas, channels = _summary_channels(data)
    schema_ids: dict[int, int] = {}
    channel_ids: dict[int, int] = {}
    n = orphans = 0
    first_ns = last_ns = None
    damaged: list[dict[str, Any]] = []
    complete = False
    with out_f:
        writer = Writer(out_f, compression=CompressionType.ZSTD)
        header_written = False
        for record in _salvaged_records(data):
            if isinstance(record, tuple):
                start, end, why = record
                damaged.append({"byte": start, "bytes": end - start, "why": why,
                                "after_s": (last_ns or 0) / 1e9, "before_s": None})
                continue
            if isinstance(record, Header):
                if not header_written:
                    writer.start(profile=record.profile, library=record.library)
                    header_written = True
                continue
            if not header_written:
                writer.start()
                header_written = True
            if isinstance(record, Schema):
                schemas.setdefault(record.id, record)
            elif isinstance(record, Channel):
                channels.setdefault(record.id, record)
            elif isinstance(record, Message):
                cid = channel_ids.get(record.channel_id)
                if cid is None:
                    ch = channels.get(record.channel_id)
                    schema = schemas.get(ch.schema_id) if ch is not None else None
                    if ch is None or (ch.schema_id and schema is None):
                        orphans += 1  # its channel or schema record was in a damaged span
                        continue
                    if schema is not None and schema.id not in schema_ids:
                        schema_ids[schema.id] = writer.register_schema(
                            schema.name, schema.encoding, schema.data)
                    cid = channel_ids[record.channel_id] = writer.register_channel(
                        ch.topic, ch.message_encoding, schema_ids.get(ch.schema_id, 0),
                        dict(ch.metadata))
                writer.add_message(cid, record.log_time, record.data, record.publish_time,
                                   record.sequence)
                n += 1
                if damaged and damaged[-1]["before_s"] is None:
                    damaged[-1]["before_s"] = record.log_time / 1e9
                first_ns = record.log_time if first_ns is None else min(first_ns,
                                                                         record.log_time)
                last_ns = record.log_time if last_ns is None else max(last_ns,
                                                                      record.log_time)
            elif isinstance(record, Metadata):
                writer.add_metadata(record.name, dict(record.metadata))
            elif isinstance(record, Attachment):
                writer.add_attachment(record.create_time, record.log_time, record.name,
                                      record.media_type, record.data)
            elif isinstance(record, Footer):
                complete = not damaged
        if not header_written:
            writer.start()
        writer.finish()
    if complete:
        stopped = "complete file"
    elif damaged and damaged[-1]["why"] == "cut off":
        stopped = f"cut off at byte {damaged[-1]['byte']}"
    else:
        stopped = "end of file"
    return {"input": str(src), "output": str(dst), "messages": n, "complete": complete,
            "stopped": stopped, "damaged": damaged, "orphaned_messages": orphans,
            "start_s": (first_ns or 0) / 1e9, "end_s": (last_ns or 0) / 1e9}


# -- CSV import (seed 000 Sec. IV: force at 100 Hz, pose interpolated to 100 Hz) ----------
CSV_REQUIRED = ("time_s", "fx_n", "fy_n", "fz_n")
CSV_POSE = ("x_m", "roll_rad", "pitch_rad")
CSV_OPTIONAL = ("y_m", "z_m")


def _quat_wxyz(roll_rad: float, pitch_rad: float, yaw_rad: float = 0.0) -> tuple[float, ...]:
    cr, sr = math.cos(roll_rad / 2), math.sin(roll_rad / 2)
    cp, sp = math.cos(pitch_rad / 2), math.sin(pitch_rad / 2)
    cy, sy = math.cos(yaw_rad / 2), math.sin(yaw_rad / 2)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)


def import_csv(src: str | Path, dst: str | Path, metadata: dict[str, Any] | None = None
               ) -> dict[str, Any]:
    """A physical robot's CSV (``time_s, fx_n, fy_n, fz_n`` and, for the estimator, the
    body pose ``x_m, roll_rad, pitch_rad``; optional ``y_m, z_m``) -> an MCAP trace with the
    same ``force`` and ``body_pose`` CAN frames a simulated beams run records."""
    from protocol import can_frames

    src = Path(src)
    try:
        f = open(src, newline="", encoding="utf-8")
    except FileNotFoundError:
        raise UserError(f"{src}: no such CSV file") from None
    except OSError as exc:
        raise UserError(f"{src}: cannot read ({exc.strerror})") from None
    with f:
        try:
            reader = csv.DictReader(f)
            header = [h.strip() for h in (reader.fieldnames or [])]
        except (csv.Error, UnicodeDecodeError) as exc:
            raise UserError(f"{src}: not a readable CSV ({_why(exc)})") from None
        missing = [c for c in CSV_REQUIRED if c not in header]
        if missing:
            raise UserError(f"{src}: CSV lacks column(s) {', '.join(missing)} "
                            f"(needs {', '.join(CSV_REQUIRED + CSV_POSE)})")
        has_pose = all(c in header for c in CSV_POSE)
        ignored = [h for h in header if h not in CSV_REQUIRED + CSV_POSE + CSV_OPTIONAL]
        reader.fieldnames = header
        meta = {"source": "import-csv", "csv": src.name}
        meta.update(metadata or {})
        out = rec.Recorder(dst, meta)
        n = 0
        last_us = -1
        try:
            for line, row in enumerate(reader, start=2):
                try:
                    vals = {k: float(row[k]) for k in header if k not in ignored and row[k] not in (None, "")}
                    t_us = int(round(vals["time_s"] * 1e6))
                    fx, fy, fz = vals["fx_n"], vals["fy_n"], vals["fz_n"]
                except (KeyError, ValueError, TypeError):
                    raise UserError(f"{src}:{line}: needs numbers in "
                                    f"{', '.join(CSV_REQUIRED)}") from None
                if t_us < 0 or t_us < last_us:
                    raise UserError(f"{src}:{line}: time_s must be >= 0 and non-decreasing")
                if not all(math.isfinite(v) for v in vals.values()):
                    raise UserError(f"{src}:{line}: non-finite value")
                last_us = t_us
                arb, data = can_frames.encode("force", fx_n=fx, fy_n=fy, fz_n=fz,
                                              sample=n)
                out.can(t_us, arb, data, direction="rx")
                if has_pose and all(k in vals for k in CSV_POSE):
                    arb, data = can_frames.encode("body_pose", x_m=vals["x_m"],
                                                  roll_rad=vals["roll_rad"],
                                                  pitch_rad=vals["pitch_rad"])
                    out.can(t_us, arb, data, direction="rx")
                    out.body_pose(t_us, (vals["x_m"], vals.get("y_m", 0.0),
                                         vals.get("z_m", 0.0)),
                                  _quat_wxyz(vals["roll_rad"], vals["pitch_rad"]))
                n += 1
            if n == 0:
                raise UserError(f"{src}: CSV has no data rows")
        except csv.Error as exc:
            out.close()
            Path(dst).unlink(missing_ok=True)
            raise UserError(f"{src}: malformed CSV ({_why(exc)})") from None
        except UserError:
            out.close()
            Path(dst).unlink(missing_ok=True)
            raise
        out.close()
    return {"input": str(src), "output": str(dst), "samples": n, "pose": has_pose,
            "ignored_columns": ignored}
