"""The MCAP writer every trace is written through: a lean one, by hand.

It uses the stock ``mcap`` record classes for everything but the messages, which are
packed straight into each chunk, and packs the message indexes by hand. Schemas and
channels go to the data section as they appear, so a file cut short keeps them ahead of
its chunks.

Why not the stock ``mcap.writer.Writer``: on the 4 324 messages of a 10 s flat-tripod
run, written chunk by chunk as the recorder writes them (the stock writer ``flush()``-ed
after each 0.5 s window, zstd), it takes 3.7-4.1x our time: 19-33 ms against 5-9 ms
(4.5-7.5 against 1.1-2.1 us a message, median of 15; ``.venv/bin/python -m bench
traces``, row "stock mcap Writer / ours"). That is 3-5 % of the run's wall time on top of
the recorder's 13 % one-core cost. And its files differ byte for byte (zstd level 3,
schemas and channels inside chunks, other index layout), so every shipped scenario's
trace would change, which the project's determinism check forbids. ``foxglove-sdk``'s
writer (Rust core) takes 1.7-1.9x our time on the same messages (row "foxglove-sdk MCAP
writer / ours"), writes to a path only, and writes other bytes too.
"""
from __future__ import annotations

import functools
import struct
import zlib
from importlib import metadata as _pkg_metadata
from typing import BinaryIO

import zstandard
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (Channel, Chunk, ChunkIndex, DataEnd, Footer, Header, Metadata,
                          MetadataIndex, Schema, Statistics, SummaryOffset)
from mcap.writer import MCAP0_MAGIC

from hexhil.trace.topics import PROFILE

_MESSAGE_HEADER = struct.Struct("<BQHIQQ")  # opcode, length, channel, sequence, times



@functools.cache
def software_version() -> str:
    """hexhil's version, for the header's library and the metadata record."""
    try:
        return _pkg_metadata.version("hexhil")
    except _pkg_metadata.PackageNotFoundError:
        return "unknown"


class TraceWriter:
    """Header and metadata, schemas and channels as they appear, one zstd chunk per
    ``chunk()`` call with its message indexes, and the summary at ``finish()``."""

    def __init__(self, f: BinaryIO, library: str) -> None:
        self.f = f
        self.b = RecordBuilder()
        self.pos = 0
        self.zstd = zstandard.ZstdCompressor(level=1)
        self.schemas: list[Schema] = []
        self.channels: list[Channel] = []
        self.metadata_indexes: list[MetadataIndex] = []
        self.chunk_indexes: list[ChunkIndex] = []
        self.counts: dict[int, int] = {}
        self.messages = 0
        self.start_ns: int | None = None
        self.end_ns = 0
        self._write(MCAP0_MAGIC)
        Header(profile=PROFILE, library=library).write(self.b)
        self._emit()

    def _write(self, data: bytes) -> None:
        self.f.write(data)
        self.pos += len(data)

    def _emit(self) -> None:
        self._write(self.b.end())

    def schema(self, sid: int, name: str, encoding: str, data: bytes) -> None:
        rec = Schema(id=sid, name=name, encoding=encoding, data=data)
        rec.write(self.b)
        self._emit()
        self.schemas.append(rec)

    def channel(self, cid: int, topic: str, encoding: str, sid: int) -> None:
        rec = Channel(id=cid, topic=topic, message_encoding=encoding, metadata={},
                      schema_id=sid)
        rec.write(self.b)
        self._emit()
        self.channels.append(rec)
        self.counts[cid] = 0

    def metadata(self, name: str, values: dict[str, str]) -> None:
        offset = self.pos
        Metadata(name=name, metadata=values).write(self.b)
        length = self.b.count
        self._emit()
        self.metadata_indexes.append(MetadataIndex(offset=offset, length=length, name=name))

    def chunk(self, msgs: list[tuple[int, int, bytes]]) -> None:
        """One zstd chunk of (log_time_ns, channel_id, data) already in log-time order,
        then its message indexes; flushed to the OS."""
        packing = ChunkPacking(msgs, self.messages)
        packing.pack(len(msgs))
        self.end_chunk(packing)

    def end_chunk(self, packing: "ChunkPacking") -> None:
        """Write a chunk whose messages are all packed (``ChunkPacking.pack``), compressed,
        then its message indexes; flushed to the OS."""
        msgs, parts, index, seq = packing.msgs, packing.parts, packing.index, packing.seq
        raw = b"".join(parts)
        comp = self.zstd.compress(raw)
        t0, t1 = msgs[0][0], msgs[-1][0]
        start = self.pos
        Chunk(compression="zstd", data=comp, message_start_time=t0, message_end_time=t1,
              uncompressed_crc=zlib.crc32(raw), uncompressed_size=len(raw)).write(self.b)
        chunk_length = self.b.count
        self._emit()
        # Message indexes packed by hand: the stock record writes each entry through
        # two calls (~1.5 us a message).
        offsets = {}
        records = []
        pos = self.pos
        counts = self.counts
        for cid in sorted(index):
            flat = index[cid]
            entries = struct.pack("<%dQ" % len(flat), *flat)
            offsets[cid] = pos
            records.append(struct.pack("<BQHI", Opcode.MESSAGE_INDEX, 6 + len(entries), cid,
                                       len(entries)))
            records.append(entries)
            pos += 15 + len(entries)
            counts[cid] += len(flat) // 2
        index_bytes = b"".join(records)
        index_length = len(index_bytes)
        self._write(index_bytes)
        self.chunk_indexes.append(ChunkIndex(
            message_start_time=t0, message_end_time=t1, chunk_start_offset=start,
            chunk_length=chunk_length, message_index_offsets=offsets,
            message_index_length=index_length, compression="zstd",
            compressed_size=len(comp), uncompressed_size=len(raw)))
        self.messages = seq
        self.start_ns = t0 if self.start_ns is None else min(self.start_ns, t0)
        self.end_ns = max(self.end_ns, t1)
        self.f.flush()

    def finish(self) -> None:
        """Data end, the summary (schemas, channels, statistics, chunk and metadata
        indexes, each group with its summary offset), the footer and the closing magic."""
        DataEnd(data_section_crc=0).write(self.b)
        self._emit()
        summary_start = self.pos
        b = RecordBuilder()
        offsets = []
        stats = Statistics(
            message_count=self.messages, schema_count=len(self.schemas),
            channel_count=len(self.channels), attachment_count=0,
            metadata_count=len(self.metadata_indexes), chunk_count=len(self.chunk_indexes),
            message_start_time=self.start_ns or 0, message_end_time=self.end_ns,
            channel_message_counts=dict(self.counts))
        for opcode, group in ((Opcode.SCHEMA, self.schemas), (Opcode.CHANNEL, self.channels),
                              (Opcode.STATISTICS, [stats]),
                              (Opcode.CHUNK_INDEX, self.chunk_indexes),
                              (Opcode.METADATA_INDEX, self.metadata_indexes)):
            if not group:
                continue
            group_start = summary_start + b.count
            for rec in group:
                rec.write(b)
            offsets.append(SummaryOffset(group_opcode=opcode, group_start=group_start,
                                         group_length=summary_start + b.count - group_start))
        offset_start = summary_start + b.count
        for o in offsets:
            o.write(b)
        summary = b.end()
        crc = zlib.crc32(summary)
        crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 20, summary_start, offset_start),
                         crc)
        self._write(summary)
        Footer(summary_start=summary_start, summary_offset_start=offset_start,
               summary_crc=crc).write(self.b)
        self._emit()
        self._write(MCAP0_MAGIC)
        self.f.flush()


class ChunkPacking:
    """A chunk's message records and index entries, packed ``pack(n)`` messages at a time,
    so an owner that waits (the recorder in a run's waits for its firmware) can do it in
    slices; ``TraceWriter.end_chunk`` writes it. ``seq``: the next message's sequence
    number, from the writer's message count (one chunk is packed at a time) to the count
    after this chunk."""

    def __init__(self, msgs: list[tuple[int, int, bytes]], seq: int) -> None:
        self.msgs, self.seq = msgs, seq
        self.parts: list[bytes] = []
        self.index: dict[int, list[int]] = {}  # channel -> [log_time, offset, log_time, ...]
        self._off = 0
        self._i = 0

    def pack(self, n: int) -> bool:
        """Pack up to ``n`` more messages; True once all are packed."""
        pack, parts, index = _MESSAGE_HEADER.pack, self.parts, self.index
        off, seq, i = self._off, self.seq, self._i
        for t, cid, data in self.msgs[i:i + n]:
            size = len(data)
            parts.append(pack(Opcode.MESSAGE, 22 + size, cid, seq & 0xFFFFFFFF, t, t))
            parts.append(data)
            idx = index.get(cid)
            if idx is None:
                idx = index[cid] = []
            idx += (t, off)
            off += 31 + size
            seq += 1
        self._off, self.seq = off, seq
        self._i = min(i + n, len(self.msgs))
        return self._i == len(self.msgs)
