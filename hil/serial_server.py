"""Serve a ``Bus`` in real time on a pseudo-terminal or a 127.0.0.1 TCP port.

Virtual time is pinned to the wall clock: bytes from the client enter the line at the
virtual time they arrived, and each reply byte is handed back only once its virtual
arrival time (wire time + return delay + wire time) has passed on the wall clock, so a
stock client (dynamixel-sdk, pyserial) sees the latency of a real bus. A pty ignores
baud, so all timing comes from here. This is the one place in ``hil`` that reads the
wall clock; lockstep runs never import it.
"""
from __future__ import annotations

import errno
import os
import select
import signal
import socket
import sys
import time
import tty
from typing import Callable

from hil.bus import Bus

MAX_WAIT_S = 0.2  # wake at least this often so timed faults and signals are handled


class Stop(Exception):
    """Raised by the SIGTERM handler to leave the serving loop cleanly."""


def _raise_stop(signum, frame) -> None:
    raise Stop()


class RealTimeServer:
    """Pins ``bus`` virtual time to the wall clock and shuttles bytes to one client."""

    def __init__(self, bus: Bus) -> None:
        self.bus = bus
        self._wall0_ns = time.monotonic_ns()
        self._v0_us = bus.clock.t_us

    def now_us(self) -> int:
        """Virtual time that corresponds to the wall clock now."""
        return self._v0_us + (time.monotonic_ns() - self._wall0_ns) // 1000

    def _catch_up(self) -> None:
        t = self.now_us()
        if t > self.bus.clock.t_us:
            self.bus.idle_until(t)

    def pump(self, fd: int, read: Callable[[], bytes | None], write: Callable[[bytes], None]) -> None:
        """Serve until ``read`` reports the client gone (None) or Stop is raised."""
        bus = self.bus
        while True:
            self._catch_up()
            out = bus.master_read(1 << 16, 0)
            if out:
                write(out)
            nxt = bus.next_rx_us()
            wait = MAX_WAIT_S if nxt is None else min(MAX_WAIT_S, max(0.0, (nxt - self.now_us()) * 1e-6))
            ready, _, _ = select.select([fd], [], [], wait)
            if ready:
                data = read()
                if data is None:
                    return
                if data:
                    self._catch_up()
                    bus.master_write(data)

    def serve_pty(self, announce: Callable[[str], None]) -> None:
        """Open a pty, announce its path, serve until SIGTERM/Ctrl-C."""
        master, slave = os.openpty()
        tty.setraw(slave)  # no echo, no line discipline: bytes pass untouched
        os.set_blocking(master, False)
        path = os.ttyname(slave)

        def read() -> bytes | None:
            try:
                return os.read(master, 4096)
            except BlockingIOError:
                return b""
            except OSError as exc:  # EIO: no client has the slave open (we hold it, so rare)
                if exc.errno == errno.EIO:
                    time.sleep(0.01)
                    return b""
                raise

        def write(data: bytes) -> None:
            try:
                os.write(master, data)
            except (BlockingIOError, OSError):
                pass  # client not reading: bytes lost, as a UART overrun

        announce(f"pty: {path}")
        try:
            self.pump(master, read, write)
        finally:
            os.close(master)
            os.close(slave)

    def serve_tcp(self, port: int, host: str, announce: Callable[[str], None]) -> None:
        """Listen on host:port; serve one client at a time until SIGTERM/Ctrl-C."""
        srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            srv.bind((host, port))
        except OSError as exc:
            srv.close()
            raise OSError(f"cannot listen on {host}:{port}: {exc.strerror}") from None
        srv.listen(1)
        announce(f"tcp: {host}:{srv.getsockname()[1]}")
        try:
            while True:
                conn, _ = srv.accept()
                conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                conn.setblocking(False)

                def read() -> bytes | None:
                    try:
                        data = conn.recv(4096)
                    except BlockingIOError:
                        return b""
                    except OSError:
                        return None
                    return data if data else None

                def write(data: bytes) -> None:
                    try:
                        conn.sendall(data)
                    except OSError:
                        pass

                try:
                    self.pump(conn.fileno(), read, write)
                finally:
                    conn.close()
        finally:
            srv.close()


def install_sigterm() -> None:
    """SIGTERM ends serving the way Ctrl-C does."""
    signal.signal(signal.SIGTERM, _raise_stop)


def flush_print(line: str) -> None:
    sys.stdout.write(line + "\n")
    sys.stdout.flush()
