"""Protocol layer speed: the Dynamixel parser's byte path and CAN frame packing, measured
under CPython (this process) and under the real ``micropython`` binary on the same data.

The parser is timed through ``Parser.push`` (what the firmware calls per received byte);
the data is a recorded-looking bus: per control cycle one SYNC_WRITE of position + speed to
18 servos and 18 READ/status pairs of Present Position, with a little line noise.
The CAN rows are ``encode`` + ``decode`` of a ``force`` frame; cantools on the same frame,
in this process, is the baseline of the ratio.
"""
from __future__ import annotations

import re
import tempfile
import time
from pathlib import Path

from bench import Row
from hexhil.protocol import can_frames
from hexhil.protocol.dynamixel import v1 as dxl
from tests.mpy import ROOT, run_micropython

CYCLES = 300
CAN_ROUNDS = 20000

MPY_SCRIPT = """
import time
from protocol.dynamixel import v1 as dxl
from protocol import can_frames as cf

with open(%(path)r, "rb") as f:
    data = f.read()
p = dxl.Parser()
push = p.push
n = len(data)
t0 = time.ticks_us()
for i in range(n):
    push(data[i])
dt = time.ticks_diff(time.ticks_us(), t0)
print("parser_bytes", n, "packets", p.packets, "us", dt)

t0 = time.ticks_us()
for i in range(%(rounds)d):
    arb_id, payload = cf.encode("force", fx_n=0.25, fy_n=-0.125, fz_n=1.5, sample=i)
    cf.decode(arb_id, payload)
dt = time.ticks_diff(time.ticks_us(), t0)
print("can_rounds", %(rounds)d, "us", dt)
"""


def bus_capture(cycles: int = CYCLES) -> bytes:
    """A deterministic stream like one control loop's traffic on an 18-servo bus."""
    out = bytearray()
    for c in range(cycles):
        entries = [(i, bytes((c & 0xFF, 2, 100, 0))) for i in range(1, 19)]
        out += dxl.sync_write(30, 4, entries)
        for i in range(1, 19):
            out += dxl.read(i, 36, 2)
            out += dxl.status(i, 0, bytes(((c + i) & 0xFF, 1)))
        if c % 10 == 0:
            out += b"\x00\x55\xaa"  # line noise between cycles
    return bytes(out)


def _cpython_parser(data: bytes) -> tuple[float, int]:
    p = dxl.Parser()
    push = p.push
    t0 = time.perf_counter()
    for b in data:
        push(b)
    return time.perf_counter() - t0, p.packets


def _cpython_can(rounds: int) -> float:
    t0 = time.perf_counter()
    for i in range(rounds):
        arb_id, payload = can_frames.encode("force", fx_n=0.25, fy_n=-0.125, fz_n=1.5,
                                            sample=i & 0xFFFF)
        can_frames.decode(arb_id, payload)
    return time.perf_counter() - t0


def _cantools_can(rounds: int) -> float:
    import cantools

    db = cantools.database.load_file(str(ROOT / "protocol" / "hexhil.dbc"))
    msg = db.get_message_by_name("force")
    t0 = time.perf_counter()
    for i in range(rounds):
        payload = msg.encode({"fx_n": 0.25, "fy_n": -0.125, "fz_n": 1.5, "sample": i & 0xFFFF})
        msg.decode(payload)
    return time.perf_counter() - t0


def _micropython(data: bytes, rounds: int) -> tuple[float, int, float]:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bus.bin"
        path.write_bytes(data)
        script = Path(tmp) / "bench_protocol_mpy.py"
        script.write_text(MPY_SCRIPT % {"path": str(path), "rounds": rounds})
        r = run_micropython(script)
    if r.returncode != 0:
        raise RuntimeError(f"micropython benchmark failed: {r.stderr.strip()}")
    m = re.search(r"parser_bytes (\d+) packets (\d+) us (\d+)", r.stdout)
    c = re.search(r"can_rounds (\d+) us (\d+)", r.stdout)
    if not (m and c) or int(m.group(1)) != len(data):
        raise RuntimeError(f"unexpected micropython output: {r.stdout!r}")
    return int(m.group(3)) / 1e6, int(m.group(2)), int(c.group(2)) / 1e6


def run() -> list[Row]:
    data = bus_capture(CYCLES)
    cpy_s, cpy_packets = _cpython_parser(data)
    mpy_s, mpy_packets, mpy_can_s = _micropython(data, CAN_ROUNDS)
    assert cpy_packets == mpy_packets == CYCLES * 37, (cpy_packets, mpy_packets)
    cpy_can_s = _cpython_can(CAN_ROUNDS)
    cantools_s = _cantools_can(CAN_ROUNDS)
    note = f"{len(data)} B, {cpy_packets} packets, Parser.push"
    cycle_bytes = len(data) / CYCLES
    return [
        Row("protocol: parser CPython", len(data) / cpy_s, "bytes/s", "", note),
        Row("protocol: parser MicroPython (unix)", len(data) / mpy_s, "bytes/s", "", note),
        Row("protocol: parser MicroPython, per 18-servo cycle", mpy_s / CYCLES * 1e6, "us",
            "", f"{cycle_bytes:.0f} B a cycle = {cycle_bytes * 10:.0f} us of wire at 1 Mbps"),
        Row("protocol: CAN force encode+decode CPython", CAN_ROUNDS / cpy_can_s, "frames/s", "",
            f"{cantools_s / cpy_can_s:.1f}x cantools encode+decode in this process"),
        Row("protocol: CAN force encode+decode MicroPython", CAN_ROUNDS / mpy_can_s, "frames/s",
            "", ""),
    ]
