"""The link conformance suite: a host that serves any link client and checks it message by
message against docs/link.md (versions 1 and 2: the script uses what both have).

The client under test is a command (the Python client: tests/link_clients/python_client.py;
a C client brings its own) that connects to the 127.0.0.1 port in ``HEXHIL_LINK_PORT`` and
follows the conformance script of docs/link.md. ``run_suite`` starts it once per session
(the script, the script with the hello answered in version 1, a version refused by the host, a host of another version, an unknown op, a
closed link) and returns one ``CaseResult`` per check; a check the session never reached
fails too. Clients run with this process's environment plus ``env``.
"""
from __future__ import annotations

import json
import os
import socket
import struct
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping, Sequence

from hexhil.hil.link.firmware_child import end_group
from hexhil.hil.link.firmware_process import Connection
from hexhil.protocol import sim_link

ROOT = Path(__file__).resolve().parents[2]
TOKEN = "conformance-7f3a"     # the config value the client must echo as a log event
PROBE_OP = 0x7A                # the unknown op the client sends when the config asks
TX = b"\x01\x02\x03"           # the script's transact: these bytes, nrx 4, timeout 500 us
NRX, TIMEOUT_US = 4, 500
RX = b"\xaa\xbb"               # what the host answers to it (fewer bytes than asked)
SWITCHES = (0x15, 0x2A, 0x3F)  # switch levels of the script's three sleep replies
BURST = 1000                   # CAN frames queued for the second sleep: split over replies


@dataclass(frozen=True)
class CaseResult:
    name: str
    passed: bool
    detail: str = ""


class Mismatch(Exception):
    """The client did something docs/link.md does not allow."""


def _expect(cond: bool, what: str) -> None:
    if not cond:
        raise Mismatch(what)


def _frames(first_id: int, n: int) -> list[tuple[int, bytes]]:
    """``n`` distinct frames, every DLC from 0 to 8, IDs counting up from ``first_id``."""
    return [((first_id + i) & 0x7FF, bytes((i + k) & 0xFF for k in range(i % 9)))
            for i in range(n)]


def _records(frames: Sequence[tuple[int, bytes]]) -> bytes:
    out = bytearray((len(frames),))
    for arb_id, data in frames:
        out += struct.pack("<HB", arb_id, len(data)) + data.ljust(8, b"\0")
    return bytes(out)


class Session:
    """One run of the client command against a listening 127.0.0.1 socket."""

    def __init__(self, command: Sequence[str], env: Mapping[str, str], timeout_s: float) -> None:
        srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        srv.bind(("127.0.0.1", 0))
        srv.listen(1)
        srv.settimeout(timeout_s)
        full_env = {**os.environ, **env, sim_link.ENV_PORT: str(srv.getsockname()[1])}
        self.timeout_s = timeout_s
        try:
            self.proc = subprocess.Popen(list(command), cwd=ROOT, env=full_env,
                                         stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                         process_group=0)
        except OSError as exc:
            srv.close()
            raise Mismatch(f"cannot start the client {' '.join(command)}: {exc}") from None
        try:
            sock, _ = srv.accept()
        except socket.timeout:
            end_group(self.proc.pid)
            self.proc.communicate()
            raise Mismatch(f"the client did not connect within {timeout_s:g} s") from None
        finally:
            srv.close()
        sock.settimeout(timeout_s)
        self.conn = Connection(sock)
        self.t_us = 0
        self.stdout = ""

    def batch(self) -> tuple[list[tuple[int, bytes]], bool]:
        try:
            return self.conn.batch()
        except socket.timeout:
            raise Mismatch(f"no request within {self.timeout_s:g} s") from None

    def request(self, op: int) -> tuple[list[tuple[int, bytes]], bytes]:
        """The next batch, which must end in request ``op``: (posted messages, its payload)."""
        msgs, closed = self.batch()
        _expect(not closed, f"the client closed the link instead of sending {chr(op)}")
        _expect(msgs[-1][0] == op, f"expected request {chr(op)}, got op 0x{msgs[-1][0]:02x}")
        return msgs[:-1], msgs[-1][1]

    def reply(self, body: bytes) -> None:
        self.conn.reply(self.t_us, body)

    def exit(self) -> tuple[int, str]:
        """The client's exit status and stderr once it has ended (killed if it hangs);
        its stdout is kept in ``stdout``."""
        try:
            out, err = self.proc.communicate(timeout=self.timeout_s)
        except subprocess.TimeoutExpired:
            end_group(self.proc.pid)
            self.proc.communicate()
            raise Mismatch(f"the client did not exit within {self.timeout_s:g} s") from None
        finally:
            self.conn.close()
        self.stdout = out.decode(errors="replace")
        return self.proc.returncode, err.decode(errors="replace")

    def close(self) -> None:
        if self.proc.poll() is None:
            end_group(self.proc.pid)
            self.proc.communicate()
        self.conn.close()


def _one_line_failure(session: Session) -> None:
    """The client must end non-zero with one line on stderr, no traceback."""
    code, err = session.exit()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    _expect(code != 0, "the client exited 0 after the link failed")
    _expect(len(lines) == 1 and not lines[0].startswith("Traceback"),
            f"expected one line on stderr, got {len(lines)}: {err.strip()[:300]!r}")


def _hello(s: Session, config: dict, version: int | None = None, switches: int = 0) -> int:
    """Answer the hello in ``version`` (default: the one the client offers); the offer."""
    _, payload = s.request(sim_link.OP_HELLO)
    _expect(len(payload) >= 2 and payload[0] in sim_link.VERSIONS,
            f"hello must start with a version of {sim_link.VERSIONS}: {payload[:8]!r}")
    _expect(all(0x20 < b < 0x7F for b in payload[1:]), "runtime name is not printable ascii")
    s.reply(bytes((payload[0] if version is None else version, switches))
            + json.dumps(config).encode())
    return payload[0]


def _log_events(msgs: list[tuple[int, bytes]]) -> list[str]:
    return [p[1:].decode(errors="replace") for op, p in msgs
            if op == sim_link.OP_EVENT and p[:1] == bytes((sim_link.EVENT_LOG,))]


def _can_echo(msgs: list[tuple[int, bytes]]) -> list[tuple[int, bytes]]:
    out = []
    for op, p in msgs:
        if op == sim_link.OP_CAN:
            _expect(len(p) >= 3 and len(p) == 3 + p[2], f"malformed CAN message {p.hex()}")
            out.append((p[0] | p[1] << 8, bytes(p[3:])))
    return out


def _sleep_request(s: Session) -> list[tuple[int, bytes]]:
    """The next sleep request; the messages posted before it."""
    posted, payload = s.request(sim_link.OP_SLEEP)
    _expect(len(payload) == 8, f"sleep payload is {len(payload)} bytes, not 8")
    (wake_us,) = struct.unpack("<Q", payload)
    _expect(wake_us > s.t_us, f"sleep to {wake_us} us is not after {s.t_us} us")
    s.t_us = wake_us
    return posted


def _sleep_reply(s: Session, flags: int, switches: int, frames: list[tuple[int, bytes]]
                 ) -> list[tuple[int, bytes]]:
    """Answer a sleep with ``frames``, split over OP_MORE replies when they do not fit;
    the messages posted in between."""
    per = sim_link.MAX_CAN_PER_REPLY
    chunks = [frames[i:i + per] for i in range(0, len(frames), per)] or [[]]
    posted = []
    for i, chunk in enumerate(chunks):
        if i:
            between, _ = s.request(sim_link.OP_MORE)
            posted += between
        more = sim_link.FLAG_MORE if i + 1 < len(chunks) else 0
        s.reply(bytes((flags | more, switches)) + _records(chunk))
    return posted


def _script(s: Session, step: Callable[[], None], version: int | None = None) -> None:
    """The conformance script, step by step (docs/link.md); ``step`` after each check. The
    hello is answered in ``version``, by default the client's offer."""
    _hello(s, {"token": TOKEN}, version)
    step()
    posted, payload = s.request(sim_link.OP_TRANSACT)
    _expect(_log_events(posted) == [TOKEN], f"config token not echoed: {_log_events(posted)}")
    step()
    _expect(payload == struct.pack("<HI", NRX, TIMEOUT_US) + TX,
            f"transact payload {payload.hex()} (expected nrx 4, timeout 500, tx 010203)")
    s.t_us += 100
    s.reply(RX)
    step()
    posted = _sleep_request(s)
    _expect([p for op, p in posted if op == sim_link.OP_WRITE] == [RX],
            "the transact's reply bytes were not written back (W)")
    step()
    few = _frames(0x100, 3)
    _sleep_reply(s, 0, SWITCHES[0], few)
    posted = _sleep_request(s)
    _expect(_can_echo(posted) == few, f"CAN echo {_can_echo(posted)} != {few}")
    _expect(_log_events(posted) == [f"switches {SWITCHES[0]}"],
            f"switch levels not seen: {_log_events(posted)}")
    step()
    burst = _frames(0x200, BURST)
    posted = _sleep_reply(s, 0, SWITCHES[1], burst)
    posted += _sleep_request(s)
    echo = _can_echo(posted)
    _expect(len(echo) == BURST, f"{len(echo)} of {BURST} queued CAN frames arrived")
    _expect(echo == burst, "the queued CAN frames arrived out of order or changed")
    step()
    _sleep_reply(s, sim_link.FLAG_END, SWITCHES[2], [])
    msgs, closed = s.batch()
    _expect(closed and not [op for op, _ in msgs if op in sim_link.REQUEST_OPS],
            "the client sent a request after the end flag instead of closing the link")
    code, err = s.exit()
    _expect(code == 0, f"exit status {code} after the end flag: {err.strip()[-300:]!r}")
    step()


def _version_1(s: Session, step: Callable[[], None]) -> None:
    """A client that offers version 2 speaks version 1 to a host that answers 1."""
    _script(s, step, sim_link.VERSION)


def _refused_version(s: Session, step: Callable[[], None]) -> None:
    s.request(sim_link.OP_HELLO)
    s.conn.reply_error("link version mismatch: this host speaks version "
                       f"{max(sim_link.VERSIONS) + 1}")
    _one_line_failure(s)
    step()


def _other_version(s: Session, step: Callable[[], None]) -> None:
    _hello(s, {}, version=max(sim_link.VERSIONS) + 1)
    _one_line_failure(s)
    step()


def _unknown_op(s: Session, step: Callable[[], None]) -> None:
    _hello(s, {"probe": "unknown_op", "token": TOKEN})
    msgs, closed = s.batch()
    _expect(not closed and msgs[0][0] == PROBE_OP, "the client did not send the probe op")
    s.conn.reply_error(f"unknown message op 0x{PROBE_OP:02x}")
    _one_line_failure(s)
    step()


def _closed_link(s: Session, step: Callable[[], None]) -> None:
    _hello(s, {})
    _, closed = s.batch()
    _expect(not closed, "the client closed the link after the hello")
    s.conn.sock.shutdown(socket.SHUT_RDWR)
    _one_line_failure(s)
    step()


ONE_LINE = "one line on stderr, non-zero exit"
SESSIONS: dict[str, tuple[Callable[[Session, Callable[[], None]], None], tuple[str, ...]]] = {
    "script": (_script, ("hello: version 1, runtime name", "hello config JSON read",
                         "uart transact", "uart write", "sleep: switches and CAN in, CAN out",
                         f"split sleep reply: {BURST} CAN frames, in order",
                         "end flag: link closed, exit 0")),
    "version_1": (_version_1, ("hello answered in version 1", "version 1: config read",
                               "version 1: uart transact", "version 1: uart write",
                               "version 1: sleep", "version 1: split sleep reply",
                               "version 1: end flag")),
    "refused_version": (_refused_version, (f"host refuses the version: {ONE_LINE}",)),
    "other_version": (_other_version, (f"host of another version: {ONE_LINE}",)),
    "unknown_op": (_unknown_op, (f"error reply to an unknown op: {ONE_LINE}",)),
    "closed_link": (_closed_link, (f"host closes the link: {ONE_LINE}",)),
}


def run_suite(command: Sequence[str], env: Mapping[str, str] | None = None,
              timeout_s: float = 30.0) -> list[CaseResult]:
    """Every session against the client ``command``; one result per check (a check after
    a failed one is not reached and is not listed)."""
    results: list[CaseResult] = []
    for name, (session_fn, checks) in SESSIONS.items():
        done = [0]

        def step() -> None:
            done[0] += 1

        detail = ""
        try:
            s = Session(command, env or {}, timeout_s)
            try:
                session_fn(s, step)
            finally:
                s.close()
        except Mismatch as exc:
            detail = str(exc)
        results += [CaseResult(f"{name}: {c}", True) for c in checks[:done[0]]]
        if detail:
            results.append(CaseResult(f"{name}: {checks[done[0]]}", False, detail))
    return results
