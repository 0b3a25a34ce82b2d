"""The fork server: AFL's, for a firmware run in this process.

A server process boots the case once and, at the first link exchange of the fuzzed window
(within ``FORK_BEFORE_S`` of it), forks one child an input. The child injects the input's
faults (``Run.inject``: the same entries a scenario's ``[faults]`` schedules, at the same
microseconds), runs to the case's end, judges the run from its trace held in memory
(held_trace.py: the boot's messages decoded once in the server, its own at the end) and
sends back its verdict; the server waits for the next input. An execution so costs the
window, not the boot. With line coverage the server puts probes in the firmware's functions
as the run is built (line_probes.py), and each child counts the lines run after the fork.
A child that sends nothing in ``HANG_WALL_S`` is a hang; one that dies is a crash.

Servers are processes of their own (``python -m hexhil.bus_fuzz.server``), started
the same way beside this process or inside a Dask worker (``run_batch``), talking in
length-prefixed pickles on two pipes. A server holds one CPU while it builds its run, so
that the recorder encodes in the run's own process (host_tools/trace/windows.py
``encode_in_for``: the held trace needs it), and all of them again from the fork on. A firmware not in process is served the same way, a fresh run an
input (execution.py ``fresh``).
"""
from __future__ import annotations

import gc
import os
import pickle
import select
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Any, BinaryIO, Callable, Sequence

from hexhil.bus_fuzz import line_probes
from hexhil.bus_fuzz.execution import (ROOT, Execution, Target, fresh, judge, probe_lines,
                                           run_input)
from hexhil.bus_fuzz.features import PacketSequence, line_features
from hexhil.bus_fuzz.held_trace import HeldTrace
from hexhil.bus_fuzz.mutations import Input
from hexhil.expect.verdicts import judged
from hexhil.protocol.errors import UserError

HANG_WALL_S = 30.0        # wall seconds an in-process execution may take: past it, a hang
FORK_BEFORE_S = 0.1       # the server forks at the first exchange this close to the window


class _Forks:
    """The server's side of the fork: at the window's first exchange it serves inputs, one
    forked child each, until its input stream ends (then it exits)."""

    def __init__(self, target: Target, inbox: BinaryIO, outbox: BinaryIO, tmp: Path) -> None:
        self.target, self.inbox, self.outbox, self.tmp = target, inbox, outbox, tmp
        self.fork_us = int(round((target.window_s - FORK_BEFORE_S) * 1e6))
        self.window_us = int(round(target.window_s * 1e6))
        self.child: tuple[int, PacketSequence] | None = None
        self.held: HeldTrace | None = None
        self.forked = False
        self.cpus: set[int] = set()      # the affinity to give back at the fork

    def setup(self, run: Any) -> None:
        """The run built: its trace held in memory (held_trace.py), the firmware's functions
        probed (before it runs: its main loop's frame too)."""
        self.held = HeldTrace(run, self.target.case)
        if self.target.coverage:
            probe_lines(self.target)

    def wrap(self, run: Any, exchange: Callable[[bytes, bool], bytes]
             ) -> Callable[[bytes, bool], bytes]:
        def hooked(data: bytes, closed: bool) -> bytes:
            if not self.forked and run.sim.clock.t_us >= self.fork_us:
                self.forked = True
                self._serve(run)         # returns in a child only
            return exchange(data, closed)
        return hooked

    def _serve(self, run: Any) -> None:
        t_us = run.sim.clock.t_us
        if t_us > self.window_us:
            _send(self.outbox, UserError(
                f"the firmware's first exchange in the last {FORK_BEFORE_S:g} s before the "
                f"window ({self.target.window_s:g} s) came at {t_us * 1e-6:g} s: start the "
                "window later"))
            os._exit(0)
        if self.cpus:
            os.sched_setaffinity(0, self.cpus)
        assert self.held is not None
        self.held.at_fork()
        gc.freeze()      # the boot's objects: a child's collections leave them (and their pages) be
        _send(self.outbox, "ready")
        n = 0
        while True:
            faults = _recv(self.inbox)
            if faults is None:
                shutil.rmtree(self.tmp, ignore_errors=True)
                os._exit(0)
            n += 1
            r, w = os.pipe()
            wall0 = time.perf_counter()
            pid = os.fork()
            if pid == 0:
                os.close(r)
                try:
                    self._child(run, faults, w)
                except BaseException as exc:   # hexhil's own error: the firmware never sees it
                    self.child = (w, PacketSequence(None))
                    self.verdict(Execution(("host error",), (f"host error: {exc!r}",),
                                           frozenset(), 0.0))
                return
            os.close(w)
            verdict = _reap(pid, r, wall0)
            try:
                _send(self.outbox, verdict)
            except BrokenPipeError:     # the campaign ended (Ctrl-C): so does the server
                shutil.rmtree(self.tmp, ignore_errors=True)
                os._exit(0)

    def _child(self, run: Any, faults: Input, w: int) -> None:
        """In the forked child: the trace held apart from the server's, the faults, the
        packet sequence, the boot's lines forgotten."""
        assert self.held is not None
        self.held.in_child()
        for m in faults:
            run.inject(m.kind.value, **m.entry())
        bus = run.sim.bus
        sequence = PacketSequence(bus.monitor)
        bus.monitor = sequence
        line_probes.reset()
        self.child = (w, sequence)

    def finish(self, summary: dict[str, Any]) -> None:
        """The child's run is over: judge it, send the verdict to the server, exit."""
        assert self.child is not None
        _, sequence = self.child
        lines = line_features(line_probes.lines()) if self.target.coverage else set()
        assert self.held is not None
        case = self.target.case
        failures, details = judge(case, summary, judged(case, self.held.recording(summary)))
        self.verdict(Execution(failures, details, frozenset(lines | sequence.pairs), 0.0))

    def verdict(self, execution: Execution) -> None:
        """Send the child's verdict to the server and exit."""
        assert self.child is not None
        with os.fdopen(self.child[0], "wb") as f:
            f.write(pickle.dumps(execution))
        os._exit(0)


def _reap(pid: int, r: int, wall0: float) -> Execution:
    """The verdict a child sends, or a crash or hang when it sends none."""
    chunks, deadline = [], time.monotonic() + HANG_WALL_S
    while True:
        left = deadline - time.monotonic()
        ready, _, _ = select.select([r], [], [], max(0.0, left))
        if not ready:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            os.close(r)
            return Execution(("firmware hung",), (f"firmware hung: no verdict in "
                                                   f"{HANG_WALL_S:g} s of wall time",),
                             frozenset(), time.perf_counter() - wall0)
        chunk = os.read(r, 1 << 16)
        if not chunk:
            break
        chunks.append(chunk)
    os.close(r)
    _, status, usage = os.wait4(pid, 0)
    wall = time.perf_counter() - wall0
    if chunks:
        return replace(pickle.loads(b"".join(chunks)), wall_s=wall,
                       cpu_s=usage.ru_utime + usage.ru_stime)
    return Execution(("host crashed",), (f"host crashed: the execution ended with status "
                                         f"{status} and no verdict",), frozenset(), wall)


def _send(stream: BinaryIO, obj: Any) -> None:
    data = pickle.dumps(obj)
    stream.write(struct.pack("<I", len(data)) + data)
    stream.flush()


def _recv(stream: BinaryIO) -> Any:
    head = stream.read(4)
    if len(head) < 4:
        return None
    (n,) = struct.unpack("<I", head)
    return pickle.loads(stream.read(n))


def serve(inbox: BinaryIO, outbox: BinaryIO) -> None:
    """A server's life: a target, then inputs until the stream ends, a verdict each."""
    target: Target = _recv(inbox)
    with tempfile.TemporaryDirectory(prefix="hexhil-fuzz-") as tmp:
        if not (target.in_process and target.fork):
            _send(outbox, "ready")
            while (faults := _recv(inbox)) is not None:
                try:
                    _send(outbox, fresh(target, faults))
                except UserError as exc:
                    _send(outbox, exc)
            return
        forks = _Forks(target, inbox, outbox, Path(tmp))
        forks.cpus = os.sched_getaffinity(0)
        os.sched_setaffinity(0, {min(forks.cpus)})
        try:
            summary = run_input(target, (), Path(tmp) / "boot.mcap", wrap=forks.wrap,
                                setup=forks.setup)
        except BaseException as exc:
            if forks.child is not None:     # in a child: hexhil's own error, as a failure
                forks.verdict(Execution(("host error",), (f"host error: {exc!r}",),
                                        frozenset(), 0.0))
            if isinstance(exc, UserError):
                _send(outbox, exc)
                return
            raise
        if forks.child is not None:
            forks.finish(summary)
        _send(outbox, UserError(f"the run ended at {summary['sim_time_s']:g} s, before the "
                                f"window ({target.window_s:g} s): the firmware stopped "
                                "during boot"))


class Server:
    """One server process: ``submit`` an input, ``result`` its verdict, in order."""

    def __init__(self, target: Target) -> None:
        env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get(
            "PYTHONPATH", ""))
        to_server, self._w = os.pipe()
        self._r, from_server = os.pipe()
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "hexhil.bus_fuzz.server", str(to_server),
             str(from_server)], pass_fds=(to_server, from_server), env=env, cwd=str(ROOT),
            stdin=subprocess.DEVNULL)
        os.close(to_server)
        os.close(from_server)
        self.outbox, self.inbox = os.fdopen(self._w, "wb"), os.fdopen(self._r, "rb")
        _send(self.outbox, target)
        first = _recv(self.inbox)
        if first != "ready":
            self.close()
            raise first if isinstance(first, UserError) else UserError(
                "the fuzzer's server ended before the window: see its output above")

    def submit(self, faults: Input) -> None:
        _send(self.outbox, faults)

    def result(self) -> Execution:
        got = _recv(self.inbox)
        if isinstance(got, UserError):
            raise got
        if got is None:
            raise UserError("the fuzzer's server ended unexpectedly: see its output above")
        return got

    def close(self) -> None:
        for f in (self.outbox, self.inbox):
            try:
                f.close()
            except OSError:
                pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


class Servers:
    """``jobs`` servers side by side; ``run`` spreads inputs over them, verdicts in order."""

    def __init__(self, target: Target, jobs: int) -> None:
        self.servers: list[Server] = []
        try:
            for _ in range(jobs):
                self.servers.append(Server(target))
        except BaseException:
            self.close()
            raise

    def run(self, inputs: Sequence[Input]) -> list[Execution]:
        """Each input to the next server free (one at a time each: a server's pipe holds
        at most one verdict, so ``select`` on it tells the truth), verdicts in input order."""
        out: dict[int, Execution] = {}
        todo = iter(range(len(inputs)))
        running: dict[int, tuple[Server, int]] = {}     # by the server's pipe descriptor

        def feed(server: Server) -> None:
            i = next(todo, None)
            if i is not None:
                server.submit(inputs[i])
                running[server.inbox.fileno()] = (server, i)

        for server in self.servers:
            feed(server)
        while running:
            ready, _, _ = select.select(list(running), [], [])
            for fd in ready:
                server, i = running.pop(fd)
                out[i] = server.result()
                feed(server)
        return [out[i] for i in range(len(inputs))]

    def close(self) -> None:
        for s in self.servers:
            s.close()


def run_batch(target: Target, inputs: Sequence[Input]) -> list[Execution]:
    """Every input on one server of its own (a Dask task: boot once, fork each)."""
    servers = Servers(target, 1)
    try:
        return servers.run(list(inputs))
    finally:
        servers.close()


def server_main(fds: Sequence[str]) -> None:
    """A server process (host_tools/bus_fuzz/server.py): its two pipes' descriptors. Ctrl-C
    is the campaign's to handle: it closes the pipes, and the server ends after the
    execution it is running."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    inbox, outbox = os.fdopen(int(fds[0]), "rb"), os.fdopen(int(fds[1]), "wb")
    try:
        serve(inbox, outbox)
    except BrokenPipeError:            # the campaign ended while this one ran an input
        pass
    finally:
        inbox.close()
        try:
            outbox.close()
        except BrokenPipeError:
            pass
