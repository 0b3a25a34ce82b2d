"""The listeners against hostile clients: the socketcand server (hil/canbus/socketcand.py),
the serial TCP server of ``hexhil bus --tcp`` and the live view of ``hexhil run --live``
(host_tools/trace/live.py) bind 127.0.0.1 by default, survive garbage and clients that
vanish mid-message, and stay bounded under a client that never reads. The socketcand
server and the live view serve every client; the serial server one at a time (the next
waits in the listen backlog)."""
from __future__ import annotations

import base64
import json
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import can
import pytest

from hexhil.hil.canbus import socketcand as can_server
from hexhil.hil.canbus.socketcand import CanServer
from hexhil.trace.live import LiveServer
from hexhil.protocol.dynamixel import v1 as dxl
from conftest import ROOT


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
    proc = subprocess.Popen([sys.executable, "-m", "hexhil.cli", "bus", "--tcp", "0"],
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


# --- the live view (host_tools/trace/live.py: foxglove-sdk's WebSocket server) ---------------
WS_KEY = base64.b64encode(b"hexhil-live-test").decode()
SUBPROTOCOL = "foxglove.sdk.v1"


def _ws_raw(port: int, rcvbuf: int = 0) -> socket.socket:
    """A WebSocket client by hand (the handshake, nothing read after it), so a test can
    make it send garbage, vanish mid-frame, or never read."""
    s = socket.socket()
    if rcvbuf:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
    s.settimeout(5)
    s.connect(("127.0.0.1", port))
    s.sendall((f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
               f"Connection: Upgrade\r\nSec-WebSocket-Key: {WS_KEY}\r\n"
               f"Sec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: {SUBPROTOCOL}\r\n\r\n"
               ).encode())
    head = b""
    while b"\r\n\r\n" not in head:
        head += s.recv(1)
    assert head.startswith(b"HTTP/1.1 101"), head
    return s


def _ws_frame(payload: bytes, opcode: int = 0x1) -> bytes:
    """One client frame (masked, as a client must; a zero mask keeps it readable)."""
    n = len(payload)
    size = bytes((0x80 | n,)) if n < 126 else bytes((0x80 | 126,)) + struct.pack(">H", n)
    return bytes((0x80 | opcode,)) + size + b"\0\0\0\0" + payload


def _ws_messages(s: socket.socket, want: int, seconds: float = 5.0) -> int:
    """Read server frames until ``want`` message-data frames (binary, op 1) came; count."""
    buf, got = b"", 0
    deadline = time.monotonic() + seconds
    while got < want and time.monotonic() < deadline:
        buf += s.recv(65536)
        while len(buf) >= 2:
            n, at = buf[1] & 0x7F, 2
            if n == 126:
                n, at = struct.unpack_from(">H", buf, 2)[0], 4
            elif n == 127:
                n, at = struct.unpack_from(">Q", buf, 2)[0], 10
            if len(buf) < at + n:
                break
            if buf[0] & 0x0F == 0x2 and buf[at] == 1:
                got += 1
            buf = buf[at + n:]
    return got


def _live_with_channel() -> tuple[LiveServer, int]:
    live = LiveServer(0)
    live.channel(7, "/test", "test", "jsonschema", b"{}", "json")
    return live, live._channels[7].id()


def _subscribe(s: socket.socket, channel_id: int) -> None:
    s.sendall(_ws_frame(json.dumps({"op": "subscribe", "subscriptions": [
        {"id": 1, "channelId": channel_id}]}).encode()))


def _receives(live: LiveServer, s: socket.socket) -> bool:
    """Log to channel 7 until ``s`` gets a message (its subscribe is read by the server's
    own threads, a moment after it was sent); False if none came in 5 s."""
    s.settimeout(0.1)
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline:
        live.log([(1_000, 7, b'{"a": 1}')])
        try:
            if _ws_messages(s, 1, 0.1):
                return True
        except socket.timeout:
            pass
    return False


def _listening(port: int) -> list[str]:
    """Local addresses (hex, as /proc/net/tcp writes them) listening on ``port``."""
    return [ln.split()[1].split(":")[0] for table in ("/proc/net/tcp", "/proc/net/tcp6")
            for ln in Path(table).read_text().splitlines()[1:]
            if ln.split()[3] == "0A" and int(ln.split()[1].split(":")[1], 16) == port]


def _rss_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise AssertionError("no VmRSS")


def test_live_server_binds_loopback_and_serves_every_client() -> None:
    live, cid = _live_with_channel()
    try:
        assert _listening(live.port) == ["0100007F"]  # 127.0.0.1 only
        clients = [_ws_raw(live.port) for _ in range(3)]
        for s in clients:
            _subscribe(s, cid)
        assert [_receives(live, s) for s in clients] == [True, True, True]
    finally:
        live.close()


def test_live_server_survives_garbage_and_clients_that_vanish_mid_message() -> None:
    live, cid = _live_with_channel()
    try:
        with socket.create_connection(("127.0.0.1", live.port)) as s:
            s.sendall(bytes(range(256)) + b"\r\n\r\n")  # not HTTP at all
        with socket.create_connection(("127.0.0.1", live.port)) as s:
            s.sendall(b"GET / HTTP/1.1\r\nUpgrade: webso")  # gone mid-handshake
        bad = _ws_raw(live.port)
        bad.sendall(_ws_frame(b"\x00\xff not json {", 0x1) + _ws_frame(b"\x07" * 40, 0x2)
                    + bytes((0x83, 0x85)) + b"junk")  # a reserved opcode
        bad.close()
        cut = _ws_raw(live.port)
        cut.sendall(_ws_frame(b'{"op": "subscribe", "subscriptions": []}' * 5)[:30])
        cut.close()  # gone mid-frame
        good = _ws_raw(live.port)
        _subscribe(good, cid)
        assert _receives(live, good)
        good.close()
    finally:
        live.close()


def test_live_server_is_bounded_under_a_client_that_never_reads() -> None:
    """512 MB offered to a subscribed client that reads nothing: the server keeps at most
    its backlog (live.BACKLOG messages) and drops the oldest, so memory stays bounded."""
    live, cid = _live_with_channel()
    try:
        lazy = _ws_raw(live.port, rcvbuf=4096)
        _subscribe(lazy, cid)
        assert _receives(live, lazy)  # subscribed: from now on the server must hold them
        payload = b'"' + b"x" * (64 * 1024 - 2) + b'"'
        before = _rss_mb()
        for i in range(8_000):
            live.log([(i, 7, payload)])
        grown = _rss_mb() - before
        assert grown < 200, f"RSS grew {grown:.0f} MB for 512 MB offered"
        lazy.close()
    finally:
        live.close()
