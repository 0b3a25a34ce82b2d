"""What the machine charges for a link round trip between the host and a micropython child:
the floor under a micropython run's two exchanges a cycle, apart from our code.
"""
from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench import Row


_ECHO_FIRMWARE = """
import socket, struct, sys, time
s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
s.connect(struct.pack("<H", socket.AF_UNIX) + sys.argv[1].encode() + b"\\0")
while True:
    msg = s.recv(64)
    if not msg:
        break
    t = time.ticks_us()
    while time.ticks_diff(time.ticks_us(), t) < msg[0] * 100:
        pass
    s.write(b"y" * 16)
"""


def _round_trip_us(micropython: Path, host_work_us: int, fw_work_us: int, n: int = 1000) -> float:
    """A link round trip between this process and a micropython child over a Unix socket
    (as a run's link), beyond the child's own work: the host busy ``host_work_us`` before each
    request (the child blocked meanwhile, as during a world step), the child
    ``fw_work_us`` before each reply (the host blocked, as during the firmware's compute).
    What the machine charges for waking a process that waited, apart from our code."""
    import socket
    with tempfile.TemporaryDirectory() as tmp, socket.socket(socket.AF_UNIX) as srv:
        prog = Path(tmp) / "echo.py"
        prog.write_text(_ECHO_FIRMWARE)
        srv.bind(str(Path(tmp) / "link"))
        srv.listen(1)
        child = subprocess.Popen([str(micropython), str(prog), srv.getsockname()])
        conn, _ = srv.accept()
        with conn:
            request, buf, spent = bytes((fw_work_us // 100,)) * 16, bytearray(64), 0.0
            for _ in range(n):
                until = time.perf_counter() + host_work_us * 1e-6
                while time.perf_counter() < until:
                    pass
                t0 = time.perf_counter()
                conn.sendall(request)
                conn.recv_into(buf)
                spent += time.perf_counter() - t0
        child.wait()
    return spent / n * 1e6 - fw_work_us


def run() -> list[Row]:
    mp = Path(sys.executable).with_name("micropython")
    rows = []
    for host_us, fw_us, what in ((0, 0, "neither side waits"),
                                 (1000, 0, "the firmware blocked 1 ms (a world step)"),
                                 (0, 500, "the host blocked 0.5 ms (the firmware's compute)")):
        rows.append(Row(f"stack link: a round trip, {what}", _round_trip_us(mp, host_us, fw_us),
                        "us", "", "a Unix socket to a micropython child, beyond its work, mean of "
                        "1,000; a micropython run makes two a cycle"))
    return rows
