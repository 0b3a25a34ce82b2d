"""The listeners against hostile clients (issue 20): the socketcand server (hil/can_server.py)
and the serial TCP server of ``hexhil bus --tcp`` bind 127.0.0.1 by default, survive
garbage and clients that vanish mid-message, and stay bounded under a client that never
reads. The socketcand server serves every client; the serial server one at a time (the
next waits in the listen backlog)."""
from __future__ import annotations

import socket
import subprocess
import sys
import time
from pathlib import Path

import can
import pytest

from hil import can_server
from hil.can_server import CanServer
from protocol import dynamixel as dxl

ROOT = Path(__file__).resolve().parent.parent


def _raw_client(port: int) -> socket.socket:
    s = socket.create_connection(("127.0.0.1", port), timeout=5)
    assert s.recv(64) == b"< hi >"
    for cmd in (b"< open hexhil0 >", b"< rawmode >"):
        s.sendall(cmd)
        assert s.recv(64) == b"< ok >"
    return s


def test_can_server_binds_loopback_and_serves_every_client() -> None:
    with CanServer(port=0) as server:
        assert server.host == "127.0.0.1"
        a, b = _raw_client(server.port), _raw_client(server.port)
        assert server.wait_for_clients(2, 5.0)
        server.publish(1_000_000, 0x700, bytes(8))
        for s in (a, b):
            s.settimeout(5)
            assert b"< frame 700 1.000000 0000000000000000 >" in s.recv(4096)
            s.close()


def test_can_server_survives_garbage_and_a_client_that_vanishes_mid_message() -> None:
    with CanServer(port=0) as server:
        bad = _raw_client(server.port)
        bad.sendall(b"\x00\xff garbage < send 7ZZ 2 01 >< send 100 9 " + b"<" + b"x" * 20000)
        bad.sendall(b"< send 100 2 01")  # cut off: the client goes away mid-command
        bad.close()
        gone = socket.create_connection(("127.0.0.1", server.port))
        gone.close()  # gone before the handshake
        good = can.Bus(interface="socketcand", host="127.0.0.1", port=server.port,
                       channel="hexhil0")
        try:
            good.send(can.Message(arbitration_id=0x200, data=b"\x01\x00", is_extended_id=False))
            deadline = time.monotonic() + 5
            got = []
            while not got and time.monotonic() < deadline:
                got = server.poll()
                time.sleep(0.01)
            assert got == [(0x200, b"\x01\x00", False)]
        finally:
            good.shutdown()


def test_can_server_drops_a_client_that_never_reads(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(can_server, "MAX_OUT_BYTES", 64 * 1024)
    with CanServer(port=0) as server:
        lazy = _raw_client(server.port)
        lazy.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        assert server.wait_for_clients(1, 5.0)
        for i in range(200_000):  # ~8 MB of frames; the cap is 64 KiB and the socket buffers
            server.publish(i, 0x700, bytes(8))
            if server.slow_clients_dropped:
                break
        deadline = time.monotonic() + 5
        while server.clients() and time.monotonic() < deadline:
            time.sleep(0.01)
        assert server.slow_clients_dropped == 1 and server.clients() == 0
        assert all(len(c.out) <= 64 * 1024 for c in server._clients)
        lazy.close()


def _serial_server() -> tuple[subprocess.Popen, int]:
    proc = subprocess.Popen([sys.executable, "-m", "host_tools.cli", "bus", "--tcp", "0"],
                            cwd=ROOT, stdout=subprocess.PIPE, text=True)
    line = proc.stdout.readline()
    assert line.startswith("tcp: 127.0.0.1:"), line
    return proc, int(line.rsplit(":", 1)[1])


def _ping(port: int) -> bytes:
    with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
        s.sendall(dxl.ping(1))
        got = b""
        while len(got) < 6:
            got += s.recv(64)
        return got


def test_serial_tcp_server_survives_garbage_vanishing_and_lazy_clients() -> None:
    proc, port = _serial_server()
    try:
        with socket.create_connection(("127.0.0.1", port)) as s:
            s.sendall(bytes(range(256)) + b"\xff\xff\x01\x09\x03")  # garbage, then cut off
        with socket.create_connection(("127.0.0.1", port)) as lazy:
            lazy.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            lazy.sendall(dxl.read(1, 0, 50) * 1_000)  # 56 kB of replies it never reads
            time.sleep(2.0)  # the line answers in real time: 1 000 READs take ~0.7 s
        assert _ping(port) == dxl.status(1, 0)
        assert proc.poll() is None
    finally:
        proc.terminate()
        proc.wait(timeout=10)
