"""Serve a ``Bus`` in real time on a pseudo-terminal or a 127.0.0.1 TCP port.

Virtual time is pinned to the wall clock: bytes from the client enter the line at the
virtual time they arrived, and each reply byte is handed back only once its virtual
arrival time (wire time + return delay + wire time) has passed on the wall clock, so a
stock client (dynamixel-sdk, pyserial) sees the latency of a real bus. A pty ignores
baud, so all timing comes from here. This is the one place in ``hil`` that reads the
wall clock; lockstep runs never import it.

The client's line settings count on a pty: the master side reads the bit rate the client
set (``line_baud``; Linux keeps one termios for both sides), and the bus judges each packet
by it against each servo's Baud Rate register (``Bus.set_master_baud``: a servo at another
rate decodes garbage, and the client garbage from it). The pty starts at the bus's rate, as
an adapter already set up, for clients that never set one.

A reply the host could not hand over in time is host lag, never a collision: the server
knows when it read the client's bytes, not when they were written, and a client cannot
have seen a reply not yet written to it. So a packet read while a status is still on its
way starts when that status has ended (``Pacing.deferred_packets``); packets read together
are fed one by one the same way. A master that talks over replies is judged exactly in
lockstep runs (``hexhil run``, the master check's ``talk_over_reply``).
"""
from __future__ import annotations

import errno
import fcntl
import os
import select
import signal
import socket
import struct
import time
import tty
from array import array
from typing import Callable, Iterator

from hexhil.hil.servobus.line import Bus

MAX_WAIT_S = 0.2  # wake at least this often so timed faults and signals are handled
LATE_US = 2_000   # one physics step (hil/world/hexapod_world.py): a step finished later is late
# Linux <asm/termbits.h>: struct termios2 is 44 bytes, c_cflag at 8, c_ispeed/c_ospeed at
# 36/40 in bit/s (any rate, BOTHER); TCGETS2 on a pty's master reads the slave's settings.
_TCGETS2, _TCSETS2 = 0x802C542A, 0x402C542B
_CBAUD, _BOTHER = 0o010017, 0o010000


class Stop(Exception):
    """Raised by the SIGTERM handler (or the end of ``--duration``) to leave serving cleanly."""


def _raise_stop(signum, frame) -> None:
    raise Stop()


def line_baud(fd: int) -> int | None:
    """The bit rate set on a tty (a pty's master: the client's), None where unknown."""
    try:
        buf = fcntl.ioctl(fd, _TCGETS2, bytes(44))
    except OSError:
        return None
    return struct.unpack_from("I", buf, 40)[0] or None


def set_line_baud(fd: int, baud: int) -> bool:
    """Set a tty's bit rate (any rate); False where the system cannot."""
    try:
        buf = bytearray(fcntl.ioctl(fd, _TCGETS2, bytes(44)))
        cflag = struct.unpack_from("I", buf, 8)[0]
        struct.pack_into("I", buf, 8, (cflag & ~_CBAUD) | _BOTHER)
        struct.pack_into("II", buf, 36, baud, baud)
        fcntl.ioctl(fd, _TCSETS2, bytes(buf))
    except OSError:
        return False
    return True


class Pacing:
    """How far the simulation lags the wall clock each time the world is advanced, and the
    client packets that waited for a status the host had not yet handed over (host lag)."""

    def __init__(self) -> None:
        self.lag_us = array("l")
        self.late = 0
        self.deferred_packets = 0
        self.deferred_us = 0
        self.reply_lag_us = array("l")     # how late each reply reached the client

    def reply(self, lag_us: int) -> None:
        self.reply_lag_us.append(max(0, lag_us))

    def add(self, lag_us: int) -> None:
        lag_us = max(0, lag_us)
        self.lag_us.append(lag_us)
        if lag_us > LATE_US:
            self.late += 1

    def summary(self) -> dict[str, float | int]:
        lags = sorted(self.lag_us)
        n = len(lags)
        rl = sorted(self.reply_lag_us)
        return {"advances": n, "late_steps": self.late, "late_threshold_ms": LATE_US / 1000,
                "deferred_packets": self.deferred_packets,
                "deferred_ms": self.deferred_us / 1000,
                "late_replies": sum(1 for x in rl if x > LATE_US),
                "reply_lag_p50_ms": rl[len(rl) // 2] / 1000 if rl else 0.0,
                "max_reply_lag_ms": rl[-1] / 1000 if rl else 0.0,
                "max_lag_ms": lags[-1] / 1000 if n else 0.0,
                "p99_lag_ms": lags[min(n - 1, (99 * n) // 100)] / 1000 if n else 0.0,
                "median_lag_ms": lags[n // 2] / 1000 if n else 0.0}


class RealTimeServer:
    """Pins ``bus`` virtual time to the wall clock and shuttles bytes to one client.

    With a world on the bus (its ``advance`` hook) the server wakes every ``step_us`` even
    when the line is idle, so physics keeps pace with the wall clock; ``pacing`` measures
    how late it is. ``on_tick(t_us)`` runs after each catch-up (recording, switches);
    ``end_us`` ends serving (``Stop``) once virtual time reaches it. Time starts at the
    master's first byte, as a robot powered on its bench waits for its board: the world
    holds still until then, so ``--duration`` counts the master's time, not the wait; a
    master that never comes ends serving once the wait itself is that long.
    """

    def __init__(self, bus: Bus, step_us: int | None = None,
                 on_tick: Callable[[int], None] | None = None, end_us: int | None = None) -> None:
        self.bus = bus
        self.step_s = MAX_WAIT_S if step_us is None else step_us * 1e-6
        self.on_tick = on_tick
        self.end_us = end_us
        self.pacing = Pacing()
        self._world_advance = bus.advance
        if bus.advance is not None:
            bus.advance = self._advance
        self._wall0_ns: int | None = None      # set at the master's first byte
        self._waiting0_ns = time.monotonic_ns()   # when serving began, before any master
        self._v0_us = bus.clock.t_us
        self._framer = bus.parser_class()      # cuts what one read brought into packets
        self.client_bauds: list[int] = []      # each bit rate the client set, in order

    def now_us(self) -> int:
        """Virtual time that corresponds to the wall clock now."""
        if self._wall0_ns is None:
            return self._v0_us
        return self._v0_us + (time.monotonic_ns() - self._wall0_ns) // 1000

    def _advance(self, t_us: int) -> None:
        self._world_advance(t_us)
        self.pacing.add(self.now_us() - t_us)

    def _catch_up(self) -> None:
        if self._wall0_ns is None and self.end_us is not None and \
                time.monotonic_ns() - self._waiting0_ns >= (self.end_us - self._v0_us) * 1000:
            raise Stop()   # no master for as long as the run was to last
        t = self.now_us()
        if self.end_us is not None and t >= self.end_us:
            t = self.end_us
        if t > self.bus.clock.t_us:
            self.bus.idle_until(t)
        if self.on_tick is not None:
            self.on_tick(self.bus.clock.t_us)
        if self.end_us is not None and t >= self.end_us:
            raise Stop()

    def _wait_s(self) -> float:
        nxt = self.bus.next_rx_us()
        wait = self.step_s
        if nxt is not None:
            wait = min(wait, max(0.0, (nxt - self.now_us()) * 1e-6))
        return wait

    def idle_ready(self) -> None:
        """What a first packet would wait for (the first catch-up: the world's and the rig's
        first tick) is done before the address is announced: ready when announced."""
        self._catch_up()

    def idle(self, fd: int) -> bool:
        """Keep the world going until ``fd`` is readable (a client knocks); True then."""
        self._catch_up()
        ready, _, _ = select.select([fd], [], [], self._wait_s())
        return bool(ready)

    def client_baud(self, baud: int | None) -> None:
        """The client's line now runs at ``baud`` (None: unknown, nothing changes)."""
        if baud and baud != self.bus.baud:
            self.bus.set_master_baud(baud)
        if baud and (not self.client_bauds or self.client_bauds[-1] != baud):
            self.client_bauds.append(baud)

    def feed(self, data: bytes) -> None:
        """The client's bytes onto the line, packet by packet, none over a status still on
        its way (see the module docstring)."""
        if self._wall0_ns is None:
            self._wall0_ns = time.monotonic_ns()
        self._catch_up()
        bus, framer, start = self.bus, self._framer, 0
        for i, byte in enumerate(data):
            if framer.push(byte, bus.clock.t_us):
                self._put(data[start:i + 1])
                start = i + 1
        if start < len(data):
            self._put(data[start:])

    def _put(self, chunk: bytes) -> None:
        bus = self.bus
        owed = bus.reply_end_us()
        if owed is not None and owed > bus.clock.t_us:
            self.pacing.deferred_packets += 1
            self.pacing.deferred_us += owed - bus.clock.t_us
            bus.idle_until(owed)
        bus.master_write(chunk)

    def pump(self, fd: int, read: Callable[[], bytes | None], write: Callable[[bytes], None],
             baud: Callable[[], int | None] | None = None) -> None:
        """Serve until ``read`` reports the client gone (None) or Stop is raised; ``baud``
        tells the client's line rate before each of its bursts is judged (a pty)."""
        bus = self.bus
        while True:
            self._catch_up()
            due = bus.next_rx_us()
            out = bus.master_read(1 << 16, 0)
            if out:
                write(out)
                if due is not None and due <= bus.clock.t_us:
                    self.pacing.reply(self.now_us() - due)
            ready, _, _ = select.select([fd], [], [], self._wait_s())
            if ready:
                data = read()
                if data is None:
                    return
                if data:
                    if baud is not None:
                        self.client_baud(baud())
                    self.feed(data)

    def serve_pty(self, announce: Callable[[str], None]) -> None:
        """Open a pty, announce its path, serve until SIGTERM/Ctrl-C."""
        master, slave = os.openpty()
        tty.setraw(slave)  # no echo, no line discipline: bytes pass untouched
        set_line_baud(slave, self.bus.baud)  # as an adapter already set up
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

        self.idle_ready()
        announce(f"pty: {path}")
        try:
            self.pump(master, read, write, lambda: line_baud(master))
        finally:
            os.close(master)
            os.close(slave)

    def listen(self, port: int, host: str, announce: Callable[[str], None],
               prefix: str) -> socket.socket:
        """A socket listening on host:port, announced as ``prefix`` + host:port once the rig
        is ready (the TCP and RFC 2217 transports)."""
        srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            srv.bind((host, port))
        except OSError as exc:
            srv.close()
            raise OSError(f"cannot listen on {host}:{port}: {exc.strerror}") from None
        srv.listen(1)
        self.idle_ready()
        announce(f"{prefix}{host}:{srv.getsockname()[1]}")
        return srv

    def clients(self, srv: socket.socket) -> Iterator[socket.socket]:
        """Each client of ``srv`` in turn, non-blocking, Nagle off; idling the rig between."""
        while True:
            if not self.idle(srv.fileno()):
                continue
            conn, _ = srv.accept()
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            conn.setblocking(False)
            yield conn

    def serve_tcp(self, port: int, host: str, announce: Callable[[str], None]) -> None:
        """Listen on host:port; serve one client at a time until SIGTERM/Ctrl-C."""
        srv = self.listen(port, host, announce, "tcp: ")
        try:
            for conn in self.clients(srv):

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

    def serve_port(self, device: str, baud: int, announce: Callable[[str], None]) -> None:
        """Serve a real serial port (a board's servo UART on a USB adapter) through pyserial."""
        import serial

        try:
            port = serial.Serial(device, baud, timeout=0, write_timeout=0)
        except (serial.SerialException, ValueError, OSError) as exc:
            raise OSError(f"cannot open {device}: {exc}") from None

        def read() -> bytes | None:
            try:
                return port.read(4096)
            except serial.SerialException:
                return None  # adapter unplugged

        def write(data: bytes) -> None:
            try:
                port.write(data)
            except serial.SerialException:
                pass

        announce(f"port: {device}")
        try:
            self.pump(port.fileno(), read, write)
        finally:
            port.close()


def install_sigterm() -> None:
    """SIGTERM ends serving the way Ctrl-C does."""
    signal.signal(signal.SIGTERM, _raise_stop)

