"""HAL back end for the simulator link: machine-like UART, switches, CAN and clock over TCP.

Each call that needs the outside world is answered by the host simulator in virtual time
(see sim_link.py), so runs are deterministic and faster than real time. Firmware compute is
charged zero virtual time: the clock only moves on bus transactions and sleeps.
Runs under MicroPython (unix port) and CPython.
"""
import json
import os
import select
import socket
import struct
import sys

from firmware.hal import base
from firmware.hal.poll_gate import PollGate, schedstat_paths
from protocol import sim_link

try:
    from time import ticks_us as _perf_us  # MicroPython
except ImportError:  # CPython
    from time import perf_counter_ns as _perf_ns

    def _perf_us():
        return _perf_ns() // 1000

RUNTIME = "micropython" if sys.implementation.name == "micropython" else "cpython"


class Link:
    """One connection to hil/link/firmware_process.py: the Unix socket at ``path`` where
    the host gives one, else TCP to ``port``. Posted messages queue in ``out`` and go out
    in the same write as the next request, so they cost no round trip.

    ``io`` replaces the socket with any object that has ``write``, ``readinto`` and
    ``close``: the host's in-process runtime passes one that answers without a socket."""

    def __init__(self, port, host="127.0.0.1", io=None, path=None):
        spin_us = 0 if io else int(os.getenv(sim_link.ENV_SPIN_US) or 0)
        host_pid = os.getenv(sim_link.ENV_HOST_PID)
        if io is None and path:
            io = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            # MicroPython's connect takes the raw sockaddr_un: u16 family, the path, NUL
            io.connect(path if RUNTIME == "cpython" else
                       struct.pack("<H", socket.AF_UNIX) + path.encode() + b"\0")
        elif io is None:
            io = socket.socket()
            try:
                io.setsockopt(6, 1, 1)  # IPPROTO_TCP, TCP_NODELAY (MicroPython lacks the names)
            except (OSError, AttributeError):
                pass
            io.connect(socket.getaddrinfo(host, port)[0][-1])
        self.sock = io
        self.io = io if hasattr(io, "readinto") else io.makefile("rwb", buffering=0)
        self.out = bytearray(8192)
        self.outmv = memoryview(self.out)
        self.nout = 0
        self.rx = bytearray(sim_link.MAX_REPLY_LEN)
        self.rxmv = memoryview(self.rx)
        self.t_us = 0
        self.io_us = 0       # wall time spent waiting on the host (profiling only)
        self.round_trips = 0
        self.dead = False    # the host closed the link or refused a message: send no more
        # the host's hint (hil/link/firmware_process.py SPIN_US): poll for each reply
        # this long before blocking, sparing the wake-up, while the gate sees free cores
        self.spin_us = spin_us if host_pid else 0
        if self.spin_us:
            self.poll = select.poll()
            self.poll.register(io, select.POLLIN)
            self.gate = PollGate(schedstat_paths(host_pid), _perf_us)

    def begin(self, op, n):
        """Reserve a message of ``n`` payload bytes; return the payload's offset in ``out``."""
        if self.nout + 3 + n > len(self.out):
            self.flush()
            if 3 + n > len(self.out):
                raise ValueError("link message too long")
        k = self.nout
        out = self.out
        out[k] = op
        out[k + 1] = n & 0xFF
        out[k + 2] = n >> 8
        self.nout = k + 3 + n
        return k + 3

    def post(self, op, payload, n):
        k = self.begin(op, n)
        self.out[k:k + n] = payload[:n] if n != len(payload) else payload

    def flush(self):
        if self.nout:
            t0 = _perf_us()
            self._write_all(self.nout)
            self.io_us += _perf_us() - t0

    def _write_all(self, n):
        mv = self.outmv
        done = 0
        while done < n:
            w = self.io.write(mv[done:n])
            done += w if w else 0
        self.nout = 0

    def _read_exact(self, n):
        mv = self.rxmv
        got = 0
        while got < n:
            k = self.io.readinto(mv[got:n])
            if not k:
                self.dead = True
                raise sim_link.LinkError("the simulator closed the link")
            got += k

    def call(self):
        """Send everything queued (ending in a request); return the reply's length.

        The reply payload is in ``rx[0:length]``; its first 8 bytes are the virtual time.
        """
        t0 = _perf_us()
        try:
            self._write_all(self.nout)
            poll = self.poll.poll if self.spin_us else None
            if poll is not None and not poll(0) and self.gate.due():
                while not poll(0) and _perf_us() - t0 < self.spin_us:
                    pass
            self._read_exact(2)
        except sim_link.LinkError as exc:   # (a bare raise: not under the native emitter)
            raise exc
        except OSError as exc:   # reset or broken pipe: the host is gone
            self.dead = True
            raise sim_link.LinkError("the simulator link failed: %s" % exc)
        length = self.rx[0] | (self.rx[1] << 8)
        if length < 8 or length > len(self.rx):
            self.dead = True
            raise sim_link.LinkError("a reply of %d bytes is outside the link's limits (8-%d)"
                                     % (length, len(self.rx)))
        self._read_exact(length)
        self.io_us += _perf_us() - t0
        self.round_trips += 1
        if self.rx[0:8] == sim_link.ERROR_MARK:
            self.dead = True
            raise sim_link.LinkError(bytes(self.rx[8:length]).decode())
        self.t_us = struct.unpack_from("<Q", self.rx, 0)[0]
        return length

    def close(self):
        try:
            if not self.dead:
                self.flush()
        finally:
            self.sock.close()
            if self.spin_us:
                self.gate.close()


class HalfDuplexUART:
    """The 1 Mbps servo line behind its direction circuit; the host turns the line round."""

    def __init__(self, link):
        self.link = link

    def write(self, buf, n):
        """Send ``buf[:n]``, no reply expected (SYNC_WRITE); posted, no round trip."""
        self.link.post(sim_link.OP_WRITE, buf, n)

    def transact(self, buf, n, rx, nrx, timeout_us):
        """Send ``buf[:n]``, then receive up to ``nrx`` bytes into ``rx``, giving up
        ``timeout_us`` of bus time after the last byte went out. Returns the count."""
        link = self.link
        k = link.begin(sim_link.OP_TRANSACT, 6 + n)
        struct.pack_into("<HI", link.out, k, nrx, timeout_us)
        link.out[k + 6:k + 6 + n] = buf[:n] if n != len(buf) else buf
        length = link.call()
        got = length - 8
        if got > 0:
            rx[0:got] = link.rxmv[8:length]
        return got


class ReadsUART(HalfDuplexUART):
    """Link version 2: a cycle's status reads go to the host in one exchange (R), which
    carries them out, retries and skips them by the master's own rule; ``transact`` then
    hands the master each attempt's bytes and time in turn, as if it had just asked."""

    def __init__(self, link):
        HalfDuplexUART.__init__(self, link)
        self._at = -1        # offset of the next attempt in ``link.rx``; -1: no reads pending
        self._left = 0
        self._t_end = 0

    def reads(self, plan, retries, echo):
        """Send ``plan``'s reads, (id, nparams, skip, nrx, timeout_us, tx) each, in one R."""
        link = self.link
        n = 1
        for item in plan:
            n += sim_link.READ_HEAD_LEN + 1 + len(item[5])
        k = link.begin(sim_link.OP_READS, n)
        out = link.out
        out[k] = len(plan)
        k += 1
        flags = sim_link.READ_ECHO if echo else 0
        for dev_id, nparams, skip, nrx, timeout_us, tx in plan:
            struct.pack_into("<BBBBBHIB", out, k, dev_id, nparams, retries, flags,
                             skip if skip >= 0 else sim_link.NO_SKIP, nrx, timeout_us, len(tx))
            k += sim_link.READ_HEAD_LEN + 1
            out[k:k + len(tx)] = tx
            k += len(tx)
        self._end = link.call()
        self._left = link.rx[8]
        self._at = 9
        self._t_end = link.t_us

    def transact(self, buf, n, rx, nrx, timeout_us):
        if self._at < 0:
            return HalfDuplexUART.transact(self, buf, n, rx, nrx, timeout_us)
        link = self.link
        p = self._at
        if not self._left or p + sim_link.ATTEMPT_HEAD_LEN > self._end:
            raise self._mismatch()
        t_us, got = struct.unpack_from("<QH", link.rx, p)
        p += sim_link.ATTEMPT_HEAD_LEN
        if got > nrx or p + got > self._end:
            raise self._mismatch()
        rx[0:got] = link.rxmv[p:p + got]
        self._at = p + got
        self._left -= 1
        link.t_us = t_us
        return got

    def reads_done(self):
        """Every attempt of the reply taken: the clock is the reply's again."""
        left, at = self._left, self._at
        self._at = -1
        self.link.t_us = self._t_end
        if left or at != self._end:
            raise self._mismatch()

    def _mismatch(self):
        self.link.dead = True
        self._at = -1
        return sim_link.LinkError("the host's reads reply does not match the firmware's reads")


class CAN(base.CAN):
    """Classic CAN port: sends are posted, receives arrive with each sleep's reply."""

    def __init__(self, link):
        base.CAN.__init__(self)
        self.link = link

    def send(self, data, arb_id):
        n = len(data)
        k = self.link.begin(sim_link.OP_CAN, 3 + n)
        out = self.link.out
        struct.pack_into("<HB", out, k, arb_id, n)
        out[k + 3:k + 3 + n] = data


class Board(base.Board):
    """Everything the firmware touches, wired to the simulator link (virtual time)."""

    def __init__(self, port=None, io=None):
        path = None
        if port is None and io is None:
            path = os.getenv(sim_link.ENV_PATH)
            if not path:
                port = int(os.getenv(sim_link.ENV_PORT) or sys.argv[-1])
        self.link = Link(port, io=io, path=path)
        self.can = CAN(self.link)
        self.switch_bits = 0
        self.switches = [base.Switch(self, i) for i in range(6)]
        self.ended = False
        # offers its newest version and speaks what the host answers (docs/link.md)
        hello = bytes((sim_link.VERSIONS[-1],)) + RUNTIME.encode()
        self.link.post(sim_link.OP_HELLO, hello, len(hello))
        length = self.link.call()
        rx = self.link.rx
        if length < 10 or rx[8] not in sim_link.VERSIONS:
            self.link.dead = True
            raise sim_link.LinkError("link version mismatch: the host speaks version %d, "
                                     "this firmware speaks %s" % (
                                         rx[8] if length > 8 else 0,
                                         " and ".join(str(v) for v in sim_link.VERSIONS)))
        self.version = rx[8]
        self.uart = (ReadsUART if self.version == sim_link.VERSION_READS
                     else HalfDuplexUART)(self.link)
        self.switch_bits = rx[9]
        self._config = json.loads(bytes(rx[10:length]).decode()) if length > 10 else {}

    def config(self):
        """Settings the host passes at boot (scenario overrides of firmware/config.py)."""
        return self._config

    def ticks_us(self):
        return self.link.t_us

    def ticks_diff(self, a, b):
        return a - b

    def ticks_add(self, a, dt):
        return a + dt

    def perf_us(self):
        return _perf_us()

    def io_us(self):
        return self.link.io_us

    def sleep_until(self, t_us):
        """End of cycle: idle the bus until ``t_us``; sample switches, collect CAN frames."""
        link = self.link
        k = link.begin(sim_link.OP_SLEEP, 8)
        struct.pack_into("<Q", link.out, k, t_us)
        flags = self._take(link.call())
        while flags & sim_link.FLAG_MORE:  # more queued frames than one reply holds
            link.begin(sim_link.OP_MORE, 0)
            flags = self._take(link.call())
        if flags & sim_link.FLAG_END:
            self.ended = True

    def _take(self, length):
        """The switches and CAN records of a sleep or more reply of ``length`` bytes; its flags."""
        rx = self.link.rx
        flags = rx[8]
        self.switch_bits = rx[9]
        n = rx[10]
        p = sim_link.SLEEP_HEAD_LEN
        if p + n * sim_link.CAN_RECORD_LEN > length:
            self.link.dead = True
            raise sim_link.LinkError("a sleep reply of %d bytes announces %d CAN frames"
                                     % (length, n))
        for _ in range(n):
            arb_id, dlc = struct.unpack_from("<HB", rx, p)
            self.can.rxq.append((arb_id, bytes(rx[p + 3:p + 3 + dlc])))
            p += sim_link.CAN_RECORD_LEN
        return flags

    def event(self, kind, text):
        data = text.encode() if isinstance(text, str) else text
        k = self.link.begin(sim_link.OP_EVENT, 1 + len(data))
        self.link.out[k] = kind
        self.link.out[k + 1:k + 1 + len(data)] = data

    def close(self):
        self.link.close()
