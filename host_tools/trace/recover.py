"""Salvage an unfinished or damaged MCAP into a finished one (``hexhil trace recover``).

This holds the one hand-written record scanner: the stock readers stop at the first bad
record, and a crashed writer leaves a cut-off tail and no summary, a bad disk a damaged
chunk in the middle. The scanner reads each top-level record by its length field, lets
the stock ``mcap`` classes parse it (a chunk must pass its CRC) and, after damage, goes on
at the next chunk that passes its CRC.
"""
from __future__ import annotations

import io
import struct
import zlib
from pathlib import Path
from typing import Any, Iterator

from mcap.reader import SeekingReader
from mcap.records import Attachment, Channel, Chunk, Footer, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.writer import CompressionType, Writer
from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoderFactory

from hexhil.trace.reader import MAGIC, check_file, why
from hexhil.trace.target import TraceTarget, partial_of
from hexhil.protocol.errors import BadFile, UserError

_OP_CHUNK = 0x06  # the chunk record's opcode (mcap.opcode.Opcode.CHUNK)
_KNOWN_OPCODES = range(0x01, 0x10)  # Header .. DataEnd
_FOOTER_BYTES = 1 + 8 + 8 + 8 + 4  # opcode, length, summary start, offsets start, CRC


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


def _schema_readable(schema: Schema) -> bool:
    """A protobuf schema parses. A schema record outside a chunk has no CRC: one with
    flipped bits would be copied, and the recovered file would not read; a good copy
    (the summary's, or a chunk's) may come later (found by fuzz/cov_targets.py)."""
    if schema.encoding != "protobuf":
        return True
    try:
        ProtobufDecoderFactory().decoder_for("protobuf", schema)
    except Exception:  # whatever the descriptor parser raises: the record is damaged
        return False
    return True


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


def _summary_intact(data: bytes) -> bool:
    """The summary section matches the footer's CRC (or the writer left it 0: unchecked).
    The stock reader does not check it, and a damaged schema there would be copied over
    the good one its chunk holds (found by fuzz/cov_targets.py's trace target)."""
    footer = len(data) - len(MAGIC) - _FOOTER_BYTES
    if footer < len(MAGIC):
        return False
    start, _, crc = struct.unpack_from("<QQI", data, footer + 9)
    return crc == 0 or (start <= footer and zlib.crc32(data[start:footer + 25]) == crc)


def _summary_channels(data: bytes) -> tuple[dict[int, Schema], dict[int, Channel]]:
    """Schemas and channels from the summary of a finished file, so that a damaged chunk
    that held a channel's first record loses only its own messages."""
    if not _summary_intact(data):
        return {}, {}
    try:
        summary = SeekingReader(io.BytesIO(data)).get_summary()
    except Exception:
        summary = None
    if summary is None:
        return {}, {}
    return ({k: v for k, v in summary.schemas.items() if _schema_readable(v)},
            dict(summary.channels))


def recover(src: str | Path, dst: str | Path, overwrite: bool = False) -> dict[str, Any]:
    """Copy every readable message of an unfinished or damaged MCAP into a finished one.

    A crashed writer leaves a cut-off tail (in ``SRC.partial`` when ``SRC`` was a run's
    target: host_tools/trace/target.py; found from ``SRC``); a bad disk leaves a damaged
    chunk in the middle.
    Both are skipped and reported: reading goes on at the next chunk that passes its CRC.
    """
    src, dst = Path(src), Path(dst)
    if not src.exists() and partial_of(src).exists():   # a killed run's unfinished file
        src = partial_of(src)
    check_file(src)
    if dst.resolve() == src.resolve() or partial_of(dst).resolve() == src.resolve():
        raise UserError(f"{dst}: recover needs a different output file")
    try:
        data = src.read_bytes()
    except OSError as exc:
        raise BadFile(f"{src}: cannot read ({exc.strerror})") from None
    target = TraceTarget(dst, overwrite)
    schemas, channels = _summary_channels(data)
    schema_ids: dict[int, int] = {}
    channel_ids: dict[int, int] = {}
    n = orphans = 0
    first_ns = last_ns = None
    damaged: list[dict[str, Any]] = []
    complete = False
    with target as out_f:
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
                if _schema_readable(record):
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
