"""Host side of the simulator link: start the firmware process and serve its requests.

The firmware (``firmware/main.py`` under ``micropython`` or CPython) connects to a
Unix socket given in ``HEXHIL_LINK_PATH`` (a firmware not ours: the 127.0.0.1 TCP port in
``HEXHIL_LINK_PORT``) and speaks ``protocol/sim_link.py``'s
framing. ``Connection.exchanges`` yields, per round trip, the messages the firmware sent
since the last reply (posted ones first, the request last); the caller answers with
``reply``. The raw bytes of both sides are kept for the recorder (``hexhil replay``).
"""
from __future__ import annotations

import os
import re
import select
import socket
import struct
import sys
import time
from pathlib import Path
from typing import Callable

from hexhil.firmware.hal.poll_gate import PollGate, schedstat_paths
from hexhil.hil.link import cores
from hexhil.protocol import sim_link
from hexhil.protocol.errors import BadFile, BadValue, UserError

# the folder that holds firmware/ and protocol/ (a clone's root, or the installed hexhil/):
# the chip's top level, where a firmware process finds them by their own names
ROOT = Path(__file__).resolve().parents[2]
REQUEST_OPS = sim_link.REQUEST_OPS
RUNTIMES = ("micropython", "cpython")
IN_PROCESS = "cpython-inprocess"   # the firmware under this CPython, in this process (sweeps)
# Our firmware's modules compiled by MicroPython's native emitter as they load: the same
# runtime calls as bytecode (every float operation: the same bits, the same serial digest),
# without its dispatch; the firmware's compute a cycle 255 -> 160 us (docs/performance.md).
# The source stays plain Python, so plain mpy-cross compiles it; a board build passes the
# same option with its target (mpy-cross -X emit=native -march=armv7emsp).
NATIVE = ("-X", "emit=native")
# How long each side polls for the other's next message before it blocks (the host sets
# sim_link.ENV_SPIN_US for its firmware): most come sooner, and a process that blocks pays
# the scheduler's wake-up on top. A micropython cycle 330 -> 260 us with both sides
# polling (docs/performance.md); each side's PollGate (firmware/hal/poll_gate.py) keeps it to where
# each side has a core.
SPIN_US = 200
# Posted messages (writes, events, CAN frames) the host holds before the request they come
# with: about 10 s of a 1 Mbaud line. More is a firmware that never waits for the host.
MAX_BATCH_BYTES = 1 << 20


class LinkViolation(Exception):
    """A client message the host cannot carry out (unknown op, malformed, another link
    version): answered with an error reply (hil/link/server.py)."""


class FirmwareError(UserError):
    """The firmware itself went wrong: it never connected to the link (``started``
    False), or broke the link's rules. One line for our own firmware; for a firmware under
    test, a verdict (hil/link/served_firmware.py: its ``FirmwareEnding``). ``last_lines`` are
    what it printed last."""

    def __init__(self, message: str, last_lines: tuple[str, ...] = (),
                 started: bool = True, exit_code: int | None = None) -> None:
        super().__init__(message)
        self.last_lines, self.started, self.exit_code = tuple(last_lines), started, exit_code


def firmware_command(python: str) -> list[str]:
    """The command line that runs the firmware under ``python`` (micropython or cpython)."""
    if python == "micropython":
        exe = Path(sys.executable).with_name("micropython")
        if not exe.exists():
            raise BadFile("the micropython binary is not in this environment "
                          "(run `make test` once, or give python cpython)", params=("python",))
        return [str(exe), *NATIVE, "-m", "firmware.main"]
    if python == "cpython":
        return [sys.executable, "-m", "firmware.main"]
    raise BadValue(f"python must be one of {', '.join(RUNTIMES)}, not {python!r}",
                   params=("python",))


def firmware_env(port: int, path: str | None = None) -> dict[str, str]:
    """The firmware's environment: where the link is (``path``, a Unix socket, instead of
    the port), how long to poll for a reply, and where its modules are."""
    env = dict(os.environ)
    env[sim_link.ENV_SPIN_US] = str(spin_us())
    env[sim_link.ENV_HOST_PID] = str(os.getpid())
    if path is None:
        env[sim_link.ENV_PORT] = str(port)
    else:
        env[sim_link.ENV_PATH] = path
    env["MICROPYPATH"] = f"{ROOT}:.frozen:{ROOT}/firmware/lib"
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    return env


def last_words(err: str, out: str = "") -> str:
    """Why a firmware stopped, in one line: the last traceback's exception with where the
    firmware raised it (micropython prints tracebacks on stdout, CPython on stderr), else
    the last line it wrote; stderr first."""
    for text in (err, out):
        lines = text.strip().splitlines()
        if not lines:
            continue
        starts = [i for i, line in enumerate(lines) if line.startswith("Traceback (most recent")]
        if not starts:
            return lines[-1]
        body = lines[starts[-1] + 1:]
        raised = next((line for line in reversed(body) if not line.startswith(" ")), body[-1])
        frames = [m for m in (_FRAME.match(line) for line in body) if m]
        own = [m for m in frames if not _hexhil_source(m.group(1))]
        if not own:
            return raised.strip()
        return f"{raised.strip()} ({Path(own[-1].group(1)).name}, line {own[-1].group(2)})"
    return "no output"


_FRAME = re.compile(r'\s+File "([^"]+)", line (\d+)')


def _hexhil_source(path: str) -> bool:
    """Whether a traceback frame is in hexhil's own board or library code, not the user's."""
    full = (ROOT / path).resolve()
    return any(full.is_relative_to(ROOT / d) for d in ("firmware/virtual_board", "firmware/hal",
                                                         "protocol"))


def split_messages(data: bytes) -> list[tuple[int, bytes]]:
    """``op | u16 len | payload`` records -> [(op, payload)]; raises ValueError if cut."""
    out = []
    i, n = 0, len(data)
    while i < n:
        if i + sim_link.HEADER_LEN > n:
            raise ValueError("link record header cut off")
        op = data[i]
        length = data[i + 1] | (data[i + 2] << 8)
        j = i + sim_link.HEADER_LEN + length
        if j > n:
            raise ValueError("link record payload cut off")
        out.append((op, bytes(data[i + sim_link.HEADER_LEN:j])))
        i = j
    return out


def runs_share_cores(runs: int) -> None:
    """This process is one of ``runs`` side by side (an executor's workers, pytest-xdist's):
    no polling (``spin_us``) unless each run's host and firmware have a CPU
    (hil/link/cores.py), as a poll on a shared one takes it from the side it waits for. A
    user's own setting stands."""
    if 2 * runs > cores.usable():
        os.environ.setdefault(sim_link.ENV_SPIN_US, "0")


def reply_bytes(t_us: int, body: bytes) -> bytes:
    """A reply as it goes on the link: u16 length, then u64 t_us and ``body`` (docs/link.md)."""
    return struct.pack("<HQ", 8 + len(body), t_us) + body


def spin_us() -> int:
    """How long this run's link polls before it blocks: ``HEXHIL_LINK_SPIN_US`` where set
    (0 turns it off), else ``SPIN_US`` where this process may use two CPUs or more
    (hil/link/cores.py: its affinity and its cgroup's CPU quota)."""
    given = os.environ.get(sim_link.ENV_SPIN_US)
    if given is not None:
        if not given.isdigit():
            raise BadValue(f"{sim_link.ENV_SPIN_US} must be a whole number of microseconds "
                           f"(0 turns polling off), not {given!r}")
        return int(given)
    return SPIN_US if cores.usable() >= 2 else 0


class Connection:
    """One firmware connection: batches of messages in, replies out. ``peer_pid``: the
    firmware's process, whose waits for a CPU tell whether polling pays (none: no polling)."""

    def __init__(self, sock: socket.socket, peer_pid: int | None = None) -> None:
        if sock.family == socket.AF_INET:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.sock = sock
        self.reader = sock.makefile("rb", buffering=65536)
        self.raw = bytearray()        # bytes of the batch being read (for the recorder)
        self.round_trips = 0
        self._poll = select.poll()
        self._poll.register(sock, select.POLLIN)
        self._spin_s = spin_us() * 1e-6 if peer_pid is not None else 0.0
        if self._spin_s:
            self._gate = PollGate(schedstat_paths(peer_pid),
                                  lambda: time.perf_counter_ns() // 1000)

    def _message(self) -> tuple[int, bytes] | None:
        try:
            return self._read_message()
        except ConnectionResetError:   # the client died with bytes unread: a closed link
            return None

    def _read_message(self) -> tuple[int, bytes] | None:
        head = self.reader.read(sim_link.HEADER_LEN)
        if len(head) < sim_link.HEADER_LEN:
            return None
        n = head[1] | (head[2] << 8)
        payload = self.reader.read(n) if n else b""
        if len(payload) < n:
            return None
        self.raw += head
        self.raw += payload
        return head[0], payload

    def batch(self) -> tuple[list[tuple[int, bytes]], bool]:
        """Messages up to and including the next request: (messages, closed). Polls for
        them for up to ``spin_us()`` before it blocks, while ``PollGate`` sees a
        core for each side."""
        self.raw = bytearray()
        poll = self._poll.poll
        if self._spin_s and not poll(0) and self._gate.due():
            until = time.perf_counter() + self._spin_s
            while not poll(0) and time.perf_counter() < until:
                pass
        msgs = []
        while True:
            m = self._message()
            if m is None:
                return msgs, True
            msgs.append(m)
            if m[0] in REQUEST_OPS:
                return msgs, False
            if len(self.raw) > MAX_BATCH_BYTES:
                raise LinkViolation(f"the firmware posted {len(self.raw):,} bytes of link "
                                    "messages without a request (a sleep, transact or line "
                                    f"read) that waits for the host; a batch holds "
                                    f"{MAX_BATCH_BYTES:,}: a loop that writes and never "
                                    "waits?")

    def reply(self, t_us: int, body: bytes = b"") -> bytes:
        """Answer the pending request; returns the raw reply bytes (length prefix included)."""
        raw = reply_bytes(t_us, body)
        self.sock.sendall(raw)
        self.round_trips += 1
        return raw

    def reply_error(self, text: str) -> None:
        """Answer the pending request with an error reply (docs/link.md); the link is over."""
        try:
            self.sock.sendall(sim_link.error_reply(text))
        except OSError:
            pass  # the client is gone already: the host reports the error either way

    def answered(self) -> bool:
        """Whether the firmware's next batch has arrived (after a reply, nothing else is
        buffered: the firmware waits for each reply before it sends more)."""
        return bool(self._poll.poll(0))

    def close(self) -> None:
        try:
            self.reader.close()
        finally:
            self.sock.close()
            if self._spin_s:
                self._gate.close()


class DirectConnection:
    """The link without a socket, for a firmware running in this process: the firmware's
    link hands over the bytes it would have written (``exchange``) and gets the reply's
    bytes back. The same frames as ``Connection``'s, so a run answers them the same way."""

    def __init__(self, answer: Callable[["DirectConnection", list[tuple[int, bytes]], bool], bool]
                 ) -> None:
        self._answer = answer
        self.raw = b""
        self.round_trips = 0
        self._reply = b""

    def exchange(self, data: bytes, closed: bool) -> bytes:
        """One batch (posted messages, then the request unless ``closed``); the reply."""
        self.raw, self._reply = data, b""
        self._answer(self, split_messages(data), closed)
        return self._reply

    def reply(self, t_us: int, body: bytes = b"") -> bytes:
        self._reply = reply_bytes(t_us, body)
        self.round_trips += 1
        return self._reply

    def reply_error(self, text: str) -> None:
        self._reply = sim_link.error_reply(text)

    def answered(self) -> bool:
        """The firmware waits on this very call: the recorder has no time to fill."""
        return True
