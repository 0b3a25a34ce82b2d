"""Live CAN for stock tools: the simulated CAN bus served over the socketcand protocol.

Stock python-can (``interface='socketcand'``), ``python -m can.viewer`` and
``cantools monitor`` attach to a running simulation through it. On the run's CAN bus
(hil/canbus/bus.py) it is a gateway: every frame on the bus reaches ``publish(t_us, arb_id,
data)`` and ``poll()`` brings in, once a step, the frames clients sent; all socket work happens on one background thread, so the
lockstep loop never blocks on a slow client.

Protocol, as python-can 4.6.1's socketcand client speaks it
(``can/interfaces/socketcand/socketcand.py``): server ``< hi >``; client
``< open CHANNEL >`` -> ``< ok >``; client ``< rawmode >`` -> ``< ok >``; then the server
sends ``< frame ID SECS.USECS HEXDATA >`` (ID 3 hex digits standard, 8 extended; data as
one unbroken hex string, since the client takes a single token) and the client sends
``< send ID DLC B0 B1 ... >``. The client reads each handshake reply with one ``recv``
and compares it exactly, so frames are held back for ``HANDSHAKE_GRACE_S`` after the
last ``< ok >`` to keep them out of that read.

No frame is lost on the link: each client's output buffer is drained, not dropped, and
``close()`` sends what is left before closing. Timestamps are virtual time in seconds, so a
tool's time axis matches the trace.

Hostile clients: it binds 127.0.0.1 unless told otherwise and serves every
client that connects (each gets every frame). Memory is bounded per client: a client
that stops reading is disconnected once ``MAX_OUT_BYTES`` of frames wait for it (it sees
the stream end rather than a silent gap; the run is never held back), and a command
longer than ``MAX_COMMAND_BYTES`` without its closing ``>`` is discarded as garbage. A
client that disconnects mid-message, or mid-handshake, is dropped alone.
"""
from __future__ import annotations

import select
import socket
import threading
import time
from collections import deque
from typing import Any

import can

DEFAULT_PORT = 29536  # socketcand's own default port
DEFAULT_CHANNEL = "hexhil0"
HANDSHAKE_GRACE_S = 0.05
MAX_OUT_BYTES = 4 << 20     # ~110 000 frame lines (about 9 min of a 200 frame/s run)
MAX_COMMAND_BYTES = 4096    # the longest real command, "< send ID 8 B0..B7 >", is 40


def frame_line(t_us: int, arb_id: int, data: bytes, is_extended_id: bool = False) -> bytes:
    """One ``< frame ... >`` record as the stock client parses it."""
    ident = "%08X" % (arb_id & 0x1FFFFFFF) if is_extended_id else "%03X" % (arb_id & 0x7FF)
    return ("< frame %s %d.%06d %s >" % (ident, t_us // 1_000_000, t_us % 1_000_000,
                                         bytes(data).hex().upper())).encode("ascii")


def parse_send(cmd: str) -> tuple[int, bytes, bool]:
    """``send ID DLC B0 B1 ...`` (the inside of ``< ... >``) -> (arb_id, data, extended)."""
    parts = cmd.split()
    if len(parts) < 3 or parts[0] != "send":
        raise ValueError("malformed send: %r" % cmd)
    ident, dlc = parts[1], int(parts[2], 16)
    data = bytes(int(b, 16) for b in parts[3:3 + dlc])
    if len(data) != dlc or dlc > 8:
        raise ValueError("send with DLC %d but %d data bytes" % (dlc, len(data)))
    return int(ident, 16), data, len(ident) > 3


class _Client:
    __slots__ = ("sock", "inbuf", "out", "channel_open", "raw", "hold_until", "peer")

    def __init__(self, sock: socket.socket, peer: tuple) -> None:
        self.sock = sock
        self.peer = peer
        self.inbuf = b""
        self.out = bytearray()
        self.channel_open = False
        self.raw = False
        self.hold_until = 0.0


class CanServer(can.Listener):
    """A socketcand server for one simulated channel, bound to 127.0.0.1 by default."""

    def __init__(self, port: int = DEFAULT_PORT, host: str = "127.0.0.1",
                 channel: str = DEFAULT_CHANNEL) -> None:
        self.channel = channel
        self._listen = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._listen.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self._listen.bind((host, port))
        self._listen.listen(8)
        self._listen.setblocking(False)
        self.host, self.port = self._listen.getsockname()[:2]
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._lock = threading.Lock()
        self._clients: list[_Client] = []
        self._inbox: deque[tuple[int, bytes, bool]] = deque()
        self._stopping = False
        self._ready = threading.Condition(self._lock)
        self.frames_published = 0
        self.frames_received = 0
        self.slow_clients_dropped = 0
        self._thread = threading.Thread(target=self._serve, name="can-server", daemon=True)
        self._thread.start()

    # -- simulator side ---------------------------------------------------------------
    def publish(self, t_us: int, arb_id: int, data: bytes, is_extended_id: bool = False) -> None:
        """Queue one frame of the simulated bus for every client in raw mode."""
        line = frame_line(t_us, arb_id, data, is_extended_id)
        with self._lock:
            self.frames_published += 1
            for c in self._clients:
                if c.raw:
                    if len(c.out) + len(line) > MAX_OUT_BYTES:
                        c.raw = False  # a client that does not read: dropped by the thread
                        c.hold_until = -1.0
                    else:
                        c.out += line
        self._wake_w.send(b"x")

    def on_message_received(self, msg: Any) -> None:
        """As a listener on the run's CAN bus (``hil.canbus.bus``): every frame to the clients."""
        self.publish(round(msg.timestamp * 1e6), msg.arbitration_id, bytes(msg.data),
                     msg.is_extended_id)

    def poll(self) -> list[tuple[int, bytes, bool]]:
        """Frames clients sent since the last call: (arb_id, data, is_extended_id)."""
        out = []
        inbox = self._inbox
        while inbox:
            out.append(inbox.popleft())
        return out

    def clients(self) -> int:
        """Clients that have finished the handshake (open + rawmode)."""
        with self._lock:
            return sum(1 for c in self._clients if c.raw)

    def wait_for_clients(self, n: int = 1, timeout_s: float = 10.0) -> bool:
        """Block until ``n`` clients are in raw mode (a run waits so no frame is missed)."""
        deadline = time.monotonic() + timeout_s
        with self._ready:
            while sum(1 for c in self._clients if c.raw) < n:
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._ready.wait(left)
        return True

    def close(self, drain_timeout_s: float = 5.0) -> None:
        """Send every queued frame (up to ``drain_timeout_s``), then stop and close."""
        deadline = time.monotonic() + drain_timeout_s
        while time.monotonic() < deadline:
            with self._lock:
                pending = any(c.out for c in self._clients)
            if not pending:
                break
            self._wake_w.send(b"x")
            time.sleep(0.005)
        self._stopping = True
        self._wake_w.send(b"x")
        self._thread.join(timeout=2.0)
        with self._lock:
            for c in self._clients:
                c.sock.close()
            self._clients.clear()
        self._listen.close()
        self._wake_r.close()
        self._wake_w.close()

    def __enter__(self) -> "CanServer":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- server thread ------------------------------------------------------------------
    def _serve(self) -> None:
        while not self._stopping:
            now = time.monotonic()
            with self._lock:
                clients = list(self._clients)
                writers = [c.sock for c in clients if c.out and c.hold_until <= now]
                held = [c.hold_until - now for c in clients if c.out and c.hold_until > now]
            timeout = min(held) if held else None
            readers = [self._listen, self._wake_r] + [c.sock for c in clients]
            r, w, _ = select.select(readers, writers, [], timeout)
            if self._wake_r in r:
                try:
                    while self._wake_r.recv(4096):
                        pass
                except BlockingIOError:
                    pass
            if self._listen in r:
                self._accept()
            for c in clients:
                if c.hold_until < 0:  # over MAX_OUT_BYTES: see publish()
                    self.slow_clients_dropped += 1
                    self._drop(c)
            by_sock = {c.sock: c for c in clients if c.hold_until >= 0}
            for s in w:
                c = by_sock.get(s)
                if c is not None:
                    self._write(c)
            for s in r:
                c = by_sock.get(s)
                if c is not None:
                    self._read(c)

    def _accept(self) -> None:
        try:
            sock, peer = self._listen.accept()
        except BlockingIOError:
            return
        try:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            sock.sendall(b"< hi >")
        except OSError:  # gone before the greeting
            sock.close()
            return
        sock.setblocking(False)
        with self._lock:
            self._clients.append(_Client(sock, peer))

    def _drop(self, c: _Client) -> None:
        with self._lock:
            if c in self._clients:
                self._clients.remove(c)
        c.sock.close()

    def _write(self, c: _Client) -> None:
        with self._lock:
            chunk = bytes(c.out[:65536])
        try:
            n = c.sock.send(chunk)
        except BlockingIOError:
            return
        except OSError:
            self._drop(c)
            return
        with self._lock:
            del c.out[:n]

    def _reply(self, c: _Client, text: bytes) -> None:
        """Handshake replies go out alone at once (the client compares each whole read);
        later ones queue behind the frames so no frame line is cut."""
        if c.raw:
            with self._lock:
                c.out += text
            return
        try:
            c.sock.setblocking(True)
            c.sock.sendall(text)
            c.sock.setblocking(False)
        except OSError:  # gone mid-handshake
            self._drop(c)

    def _read(self, c: _Client) -> None:
        try:
            data = c.sock.recv(65536)
        except BlockingIOError:
            return
        except OSError:
            data = b""
        if not data:
            self._drop(c)
            return
        c.inbuf += data
        while True:
            start = c.inbuf.find(b"<")
            end = c.inbuf.find(b">", start + 1)
            if start < 0 or end < 0:
                if start < 0 or len(c.inbuf) > MAX_COMMAND_BYTES:
                    c.inbuf = b""
                return
            cmd = c.inbuf[start + 1:end].decode("ascii", "replace").strip()
            c.inbuf = c.inbuf[end + 1:]
            self._command(c, cmd)

    def _command(self, c: _Client, cmd: str) -> None:
        word = cmd.split(" ", 1)[0]
        if word == "open":
            name = cmd[4:].strip()
            if name != self.channel:
                self._reply(c, b"< error could not open bus '%s' >" % name.encode())
                return
            c.channel_open = True
            self._reply(c, b"< ok >")
        elif word == "rawmode" and c.channel_open:
            self._reply(c, b"< ok >")
            with self._ready:
                c.hold_until = time.monotonic() + HANDSHAKE_GRACE_S
                c.raw = True
                self._ready.notify_all()
        elif word == "send" and c.raw:
            try:
                frame = parse_send(cmd)
            except ValueError as exc:
                self._reply(c, b"< error %s >" % str(exc).encode())
                return
            self._inbox.append(frame)
            self.frames_received += 1
        elif word == "echo":
            self._reply(c, b"< echo >")
        else:
            self._reply(c, b"< error unknown command >")
