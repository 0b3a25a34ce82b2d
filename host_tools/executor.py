"""Where an experiment's runs execute: this process, local worker processes, or a Dask
distributed cluster. Every run is a pure function of its spec (scenario + seed), so results
do not depend on where or in what order runs finish; they come back in spec order.

Runs done are reported through a ``Progress`` callback (the CLI draws a bar with the
estimated time left).
"""
from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import socket
from urllib.parse import urlsplit
from typing import Any, Callable, Sequence

from hexhil.hil.link.firmware_process import runs_share_cores
from hexhil.extras import require
from hexhil.progress import Progress, report
from hexhil.protocol.errors import BadFile, BadValue, TimedOut, UserError


class Executor:
    """Map a run function over specs, reporting each run done to ``progress``.

    ``workers`` = 1 runs in this process; more uses a local process pool; ``scheduler``
    (``tcp://host:port``) sends runs to an existing Dask distributed cluster instead.
    """

    def __init__(self, workers: int = 1, scheduler: str | None = None,
                 progress: Progress | None = None) -> None:
        if workers < 1:
            raise BadValue(f"workers must be at least 1, got {workers}", params=("workers",))
        if scheduler:
            require("distributed")
        self.workers = workers
        self.scheduler = scheduler
        self.progress = progress

    def map(self, fn: Callable[[Any], Any], specs: Sequence[Any], desc: str) -> list[Any]:
        def done(n: int) -> None:
            report(self.progress, desc, n, len(specs))

        if self.scheduler:
            client = dask_client(self.scheduler)    # refused before the progress starts
            done(0)
            return self._dask(client, fn, specs, done)
        done(0)
        if self.workers == 1 or len(specs) <= 1:
            out = []
            for s in specs:
                out.append(fn(s))
                done(len(out))
            return out
        return self._local(fn, specs, done)

    def _local(self, fn: Callable[[Any], Any], specs: Sequence[Any],
               done: Callable[[int], None]) -> list[Any]:
        results: list[Any] = [None] * len(specs)
        # forkserver: children never inherit MuJoCo or socket state from this process
        ctx = multiprocessing.get_context("forkserver")
        n = min(self.workers, len(specs))
        with cf.ProcessPoolExecutor(max_workers=n, mp_context=ctx, initializer=runs_share_cores,
                                    initargs=(n,)) as pool:
            futures = {pool.submit(fn, s): i for i, s in enumerate(specs)}
            for n, fut in enumerate(cf.as_completed(futures), 1):
                results[futures[fut]] = fut.result()
                done(n)
        return results

    @staticmethod
    def _dask(client: Any, fn: Callable[[Any], Any], specs: Sequence[Any],
              done: Callable[[int], None]) -> list[Any]:
        from distributed import as_completed

        try:
            futures = client.map(fn, list(specs), pure=False)
            index = {f.key: i for i, f in enumerate(futures)}
            results: list[Any] = [None] * len(specs)
            for n, fut in enumerate(as_completed(futures), 1):
                results[index[fut.key]] = fut.result()
                done(n)
            return results
        finally:
            client.close()


def dask_client(scheduler: str) -> Any:
    """A ``distributed.Client`` on ``scheduler``, or a UserError saying why not. A TCP
    address is tried first, so a refused one is named at once: Dask's own connect retries
    it until its timeout (10 s here)."""
    require("distributed")
    from distributed import Client

    _probe(scheduler)
    try:
        return Client(scheduler, timeout="10s")
    except (OSError, ValueError) as exc:
        raise _unreached(scheduler, exc) from None


def _probe(scheduler: str) -> None:
    parts = urlsplit(scheduler)
    try:
        port = parts.port
    except ValueError:
        raise BadValue(f"Dask scheduler {scheduler!r}: the port is not a number") from None
    if parts.scheme != "tcp" or not parts.hostname or port is None:
        return
    try:
        socket.create_connection((parts.hostname, port), timeout=10).close()
    except OSError as exc:
        raise _unreached(scheduler, exc) from None


def _unreached(scheduler: str, exc: Exception) -> UserError:
    kind = (TimedOut if isinstance(exc, TimeoutError) else
            BadFile if isinstance(exc, OSError) else BadValue)
    return kind(f"cannot reach Dask scheduler {scheduler}: {exc}")
