"""Traces: recording overhead on a real run, trace read (replay) rate, recorder write rate,
our MCAP writer against the stock one, and ``hexhil trace cat`` on a 30 s run.

Overhead: the same scenario run with and without a recorder in this process, alternated
and repeated, the median of the pairs' overheads; once as a user runs it (the OS places
the firmware process: the recorder encodes while the firmware computes) and once with
host and firmware pinned to one core (nothing can overlap, so the overhead is the
recorder's whole CPU cost). Read rate:
``Trace.messages`` (what replay, export and estimate read through) against the stock mcap
reader in log-time order on the same file. Writers:
a real run's messages, chunk by chunk as the recorder wrote them, through
``hexhil.trace.writer.TraceWriter`` and through ``mcap.writer.Writer`` (zstd,
``flush()`` after each chunk so it keeps the same crash-safety windows).
"""
from __future__ import annotations

import contextlib
import io
import os
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from bench import Row

SCENARIO = "scenarios/flat-tripod.toml"
RUN_S = 10.0
REPEATS = 15
READ_MESSAGES = 200_000
WRITER_REPEATS = 15
CAT_S = 30.0  # the trace `hexhil trace cat` is timed on


def _time_inside_recorder(run, out: Path) -> float:
    """Seconds spent inside Recorder methods during one recorded run (a noise-free view
    of the same overhead: it does not depend on what else the shared machine runs)."""
    from hexhil.trace import recorder as rec_mod

    spent = [0.0]
    depth = [0]   # serial_stream may call serial: counted once
    saved = {}
    for name in ("__init__", "serial", "serial_stream", "can", "link", "telemetry",
                 "switch_edge", "fault", "servo_state", "body_pose", "joints", "advance",
                 "idle", "close"):
        f = saved[name] = getattr(rec_mod.Recorder, name)

        def timed(self, *a, _f=f, **k):
            t0 = time.perf_counter()
            depth[0] += 1
            try:
                return _f(self, *a, **k)
            finally:
                depth[0] -= 1
                if not depth[0]:
                    spent[0] += time.perf_counter() - t0
        setattr(rec_mod.Recorder, name, timed)
    try:
        run(SCENARIO, RUN_S, out=str(out), overwrite=True)
    finally:
        for name, f in saved.items():
            setattr(rec_mod.Recorder, name, f)
    return spent[0]


def _pairs(run, out: Path) -> tuple[list[float], list[float]]:
    """``REPEATS`` runs without and with ``--out``, alternated: (plain s, recorded s)."""
    plain, recorded = [], []
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        run(SCENARIO, RUN_S)
        plain.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        run(SCENARIO, RUN_S, out=str(out), overwrite=True)
        recorded.append(time.perf_counter() - t0)
    return plain, recorded


def _overhead(tmp: Path) -> list[Row]:
    """The overhead of each pair of neighbouring runs, median over the pairs: the machine
    is shared and its load drifts, so a pair sees the same conditions and the median
    ignores the disturbed ones (best-of each side compares two outliers)."""
    from hexhil.run_summary import run

    out = tmp / "run.mcap"
    run(SCENARIO, 1.0)  # warm-up: imports, MuJoCo model build, micropython start
    run(SCENARIO, 1.0, out=str(out), overwrite=True)
    rows = []
    cores = os.sched_getaffinity(0)
    for pinned in (False, True):
        if pinned:  # the firmware child inherits it; lockstep runs fastest on one core
            os.sched_setaffinity(0, {min(cores)})
        try:
            plain, recorded = _pairs(run, out)
            if pinned:
                inside = min(_time_inside_recorder(run, out) for _ in range(3))
        finally:
            os.sched_setaffinity(0, cores)
        ratios = sorted(b / a - 1 for a, b in zip(plain, recorded))
        where = ("host and firmware pinned to one core, nothing overlaps: the CPU cost"
                 if pinned else "unpinned, as hexhil runs")
        rows.append(Row(f"traces: recording overhead (wall, {'one core' if pinned else 'free'})",
                        100 * statistics.median(ratios), "%", "" if pinned else "<= 10 %",
                        f"{SCENARIO} {RUN_S:g} s simulated, {where}, median of {REPEATS} "
                        f"alternated pairs (range {100 * ratios[0]:.1f}-{100 * ratios[-1]:.1f} "
                        f"%); medians {statistics.median(plain):.3f} s plain, "
                        f"{statistics.median(recorded):.3f} s with --out"))
    from hexhil.trace.reader import info

    n = info(out)["messages"]
    rows.append(Row("traces: time inside the recorder", 100 * inside / statistics.median(plain),
                    "% of run", "", f"{inside * 1e3:.1f} ms in Recorder calls per recorded run "
                    f"({n} messages), one core, best of 3"))
    return rows


def _rates(tmp: Path) -> list[Row]:
    from hexhil.trace.recorder import Recorder
    from hexhil.trace.reader import Trace
    from hexhil.protocol import can_frames
    from hexhil.protocol.dynamixel import v1 as dynamixel

    path = tmp / "big.mcap"
    pkt = dynamixel.read(1, 36, 2)
    arb, data = can_frames.encode("force", fx_n=0.1, fy_n=0.0, fz_n=-0.2, sample=1)
    t0 = time.perf_counter()
    with Recorder(path, {}, decode_serial=False, decode_can=False) as r:
        for i in range(READ_MESSAGES // 2):
            r.serial(i * 100, "tx", pkt)
            r.can(i * 100 + 50, arb, data)
    write_s = time.perf_counter() - t0
    with Trace(path) as tr:
        t0 = time.perf_counter()
        n = sum(1 for _ in tr.messages())
        ours = n / (time.perf_counter() - t0)
        t0 = time.perf_counter()
        m = sum(1 for _ in tr.reader.iter_messages(log_time_order=True))
        stock = m / (time.perf_counter() - t0)
    return [
        Row("traces: read/replay rate", ours, "msg/s", ">= 200000",
            f"Trace.messages on {n} messages, log-time order (chunk by chunk in file order "
            f"through mcap's Chunk.read and breakup_chunk: chunks do not overlap); "
            f"{ours / stock:.1f}x the stock reader's log-time merge ({stock:,.0f} msg/s)"),
        Row("traces: recorder write rate", READ_MESSAGES / write_s, "msg/s", "",
            "serial + raw CAN, protobuf, zstd chunks per 0.5 s of virtual time"),
    ]


def _replay(tmp: Path) -> list[Row]:
    from hexhil.replay import replay_firmware
    from hexhil.run_summary import run

    out = tmp / "replay.mcap"
    run(SCENARIO, RUN_S, out=str(out), overwrite=True)
    t0 = time.perf_counter()
    r = replay_firmware(out)
    dt = time.perf_counter() - t0
    assert r.identical, r.divergence
    return [Row("traces: replay into firmware", RUN_S / dt, "x real time", "",
                f"{r.exchanges} link exchanges of {RUN_S:g} s under micropython in {dt:.2f} s, "
                "identical")]


def _run_chunks(path: Path) -> tuple[list[Any], list[Any], list[list[tuple[int, int, bytes]]]]:
    """A trace's schemas, channels and, chunk by chunk, its (log_time_ns, channel, data)."""
    from mcap.records import Channel, Chunk, Message, Schema
    from mcap.stream_reader import StreamReader, breakup_chunk

    schemas, channels, chunks = [], [], []
    with open(path, "rb") as f:
        for record in StreamReader(f, emit_chunks=True).records:
            if isinstance(record, Schema):
                schemas.append(record)
            elif isinstance(record, Channel):
                channels.append(record)
            elif isinstance(record, Chunk):
                chunks.append([(m.log_time, m.channel_id, m.data) for m in breakup_chunk(record)
                               if isinstance(m, Message)])
    return schemas, channels, chunks


def _write_ours(schemas: list[Any], channels: list[Any],
                chunks: list[list[tuple[int, int, bytes]]]) -> int:
    from hexhil.trace.writer import TraceWriter

    buf = io.BytesIO()
    w = TraceWriter(buf, "hexhil bench")
    w.metadata("hexhil", {"bench": "writer"})
    for s in schemas:
        w.schema(s.id, s.name, s.encoding, s.data)
    for c in channels:
        w.channel(c.id, c.topic, c.message_encoding, c.schema_id)
    for msgs in chunks:
        w.chunk(msgs)
    w.finish()
    return len(buf.getvalue())


def _write_stock(schemas: list[Any], channels: list[Any],
                 chunks: list[list[tuple[int, int, bytes]]]) -> int:
    from mcap.writer import CompressionType, Writer

    buf = io.BytesIO()
    w = Writer(buf, compression=CompressionType.ZSTD)
    w.start(profile="", library="hexhil bench")
    w.add_metadata("hexhil", {"bench": "writer"})
    sid = {s.id: w.register_schema(s.name, s.encoding, s.data) for s in schemas}
    cid = {c.id: w.register_channel(c.topic, c.message_encoding, sid[c.schema_id])
           for c in channels}
    seq = 0
    for msgs in chunks:
        for t, c, data in msgs:
            w.add_message(cid[c], t, data, t, seq)
            seq += 1
        w.flush()  # one chunk a window, as the recorder writes them
    w.finish()
    return len(buf.getvalue())


def _write_sdk(schemas: list[Any], channels: list[Any],
               chunks: list[list[tuple[int, int, bytes]]], path: Path) -> int:
    """foxglove-sdk's MCAP writer (Rust core), one chunk a window as the recorder writes."""
    import foxglove
    from foxglove.mcap import MCAPCompression, MCAPWriteOptions

    ctx = foxglove.Context()
    w = foxglove.open_mcap(str(path), allow_overwrite=True, context=ctx,
                           writer_options=MCAPWriteOptions(compression=MCAPCompression.Zstd,
                                                           chunk_size=None))
    w.write_metadata("hexhil", {"bench": "writer"})
    sch = {s.id: foxglove.Schema(name=s.name, encoding=s.encoding, data=s.data) for s in schemas}
    ch = {c.id: foxglove.Channel(c.topic, schema=sch[c.schema_id],
                                 message_encoding=c.message_encoding, context=ctx)
          for c in channels}
    for msgs in chunks:
        for t, c, data in msgs:
            ch[c].log(data, log_time=t)
        w.flush()
    w.close()
    return path.stat().st_size


def _writers(tmp: Path) -> list[Row]:
    """The same messages of a real run through our writer and the stock one, alternated,
    median of ``WRITER_REPEATS`` each."""
    from hexhil.run_summary import run

    out = tmp / "writers.mcap"
    run(SCENARIO, RUN_S, out=str(out), overwrite=True)
    schemas, channels, chunks = _run_chunks(out)
    n = sum(len(c) for c in chunks)
    times: dict[str, list[float]] = {"ours": [], "stock": [], "sdk": []}
    sizes = {}
    writers = (("ours", _write_ours), ("stock", _write_stock),
               ("sdk", lambda *a: _write_sdk(*a, tmp / "sdk.mcap")))
    for _ in range(WRITER_REPEATS):
        for name, write in writers:
            t0 = time.perf_counter()
            sizes[name] = write(schemas, channels, chunks)
            times[name].append(time.perf_counter() - t0)
    ours, stock, sdk = (statistics.median(times[k]) for k in ("ours", "stock", "sdk"))
    return [Row("traces: stock mcap Writer / ours", stock / ours, "x time", "",
                f"{n} messages of {SCENARIO} {RUN_S:g} s in {len(chunks)} chunks, median of "
                f"{WRITER_REPEATS}: ours {ours * 1e3:.1f} ms ({1e6 * ours / n:.2f} us/msg, "
                f"{sizes['ours']} B), stock zstd {stock * 1e3:.1f} ms "
                f"({1e6 * stock / n:.2f} us/msg, {sizes['stock']} B)"),
            Row("traces: foxglove-sdk MCAP writer / ours", sdk / ours, "x time", "",
                f"the same messages: foxglove-sdk {sdk * 1e3:.1f} ms ({1e6 * sdk / n:.2f} "
                f"us/msg, {sizes['sdk']} B, to a file), ours {ours * 1e3:.1f} ms to memory")]


def _cat(tmp: Path) -> list[Row]:
    """``hexhil trace cat`` (in this process, output discarded) of a 30 s run's trace."""
    from hexhil.cli import main
    from hexhil.run_summary import run

    out = tmp / "cat.mcap"
    run(SCENARIO, CAT_S, out=str(out), overwrite=True)
    rows = []
    for label, extra in (("every topic", []), ("/can/raw", ["--topics", "/can/raw"])):
        spent = []
        for _ in range(5):
            with open(os.devnull, "w") as sink, contextlib.redirect_stdout(sink):
                t0 = time.perf_counter()
                main(["trace", "cat", str(out), *extra])
                spent.append(time.perf_counter() - t0)
        rows.append(Row(f"traces: trace cat, {label}", 1e3 * statistics.median(spent), "ms", "",
                        f"{SCENARIO} {CAT_S:g} s simulated, median of 5, in process"))
    return rows


def run() -> list[Row]:
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        return (_overhead(tmp) + _rates(tmp) + _writers(tmp) + _cat(tmp) + _replay(tmp))
