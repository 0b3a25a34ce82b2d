"""What debugging an ELF costs: ``--coverage`` against the same run without it (CPU time of
the C tripod ELF on flat-tripod, median of ``REPEATS``), and a GDB single step's round trip
on ``--gdb`` (``vCont;s`` answered by the stop, over TCP on 127.0.0.1, median of ``STEPS``)."""
from __future__ import annotations

import resource
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench import Row
from hexhil import Run
from hexhil.c_sdk import build

ROOT = Path(__file__).resolve().parent.parent
MAIN = ROOT / "examples" / "c_tripod" / "main.c"
DURATION_S = 5.0
REPEATS = 3
STEPS = 200


def _cpu_s() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    return own.ru_utime + own.ru_stime


def _packet(conn: socket.socket, body: str) -> bytes:
    raw = body.encode()
    conn.sendall(b"$" + raw + b"#%02x" % (sum(raw) & 0xFF))
    buf = b""
    while not (b"#" in buf and len(buf) >= buf.index(b"#") + 3):
        buf += conn.recv(4096)
    return buf


def _step_s(elf: Path) -> float:
    """The median round trip of a single step, in seconds."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    server = subprocess.Popen([sys.executable, "-m", "hexhil.cli", "run",
                               "scenarios/flat-tripod.toml", "--firmware", str(elf),
                               "--duration", "1", "--quiet", "--gdb", str(port)], cwd=ROOT,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        for _ in range(600):
            try:
                conn = socket.create_connection(("127.0.0.1", port))
                break
            except OSError:
                time.sleep(0.1)
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        _packet(conn, "QStartNoAckMode")
        conn.sendall(b"+")
        times = []
        for _ in range(STEPS):
            t0 = time.perf_counter()
            _packet(conn, "vCont;s")
            times.append(time.perf_counter() - t0)
        conn.sendall(b"$D#44")
        conn.close()
        server.wait(timeout=300)
    finally:
        if server.poll() is None:
            server.kill()
    return statistics.median(times)


def run() -> list[Row]:
    cpu: dict[bool, list[float]] = {False: [], True: []}
    with tempfile.TemporaryDirectory() as tmp:
        elf = build([str(MAIN)], Path(tmp) / "c_tripod.elf", target="stm32f411")
        for _ in range(REPEATS):
            for covered in (False, True):
                c0 = _cpu_s()
                Run("scenarios/flat-tripod.toml", seed=1, duration_s=DURATION_S, firmware=elf,
                    coverage=Path(tmp) / "c.info" if covered else None).run()
                cpu[covered].append(_cpu_s() - c0)
        step = _step_s(elf)
    plain, covered = statistics.median(cpu[False]), statistics.median(cpu[True])
    return [
        Row("c_tripod ELF with --coverage / without", covered / plain, "ratio", "<= 2",
            f"{DURATION_S:g} s flat-tripod, CPU median of {REPEATS}: {plain:.2f} s without, "
            f"{covered:.2f} s with (the LCOV of its own sources written)"),
        Row("GDB stepi round trip", step * 1e3, "ms", "< 50",
            f"median of {STEPS} vCont;s on --gdb, no-ack mode, TCP_NODELAY"),
    ]
