"""Where an experiment's runs execute: this process, local worker processes, or a Dask
distributed cluster. Every run is a pure function of its spec (scenario + seed), so results
do not depend on where or in what order runs finish; they come back in spec order.

A tqdm progress bar on stderr shows runs done and the estimated time left; ``on_result``
hands each result to the caller as it comes (a command's own progress display).
"""
from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import sys
from typing import Any, Callable, Sequence

from tqdm import tqdm

from protocol.errors import UserError


class Executor:
    """Map a run function over specs with a progress bar.

    ``workers`` = 1 runs in this process; more uses a local process pool; ``scheduler``
    (``tcp://host:port``) sends runs to an existing Dask distributed cluster instead.
    """

    def __init__(self, workers: int = 1, scheduler: str | None = None, progress: bool = True) -> None:
        if workers < 1:
            raise UserError(f"--workers must be at least 1, got {workers}")
        self.workers = workers
        self.scheduler = scheduler
        self.progress = progress

    def map(self, fn: Callable[[Any], Any], specs: Sequence[Any], desc: str,
            on_result: Callable[[Any], None] | None = None) -> list[Any]:
        bar = tqdm(total=len(specs), desc=desc, unit="run", file=sys.stderr, disable=not self.progress,
                   dynamic_ncols=True)
        try:
            if self.scheduler:
                return self._dask(fn, specs, bar, on_result)
            if self.workers == 1 or len(specs) <= 1:
                out = []
                for s in specs:
                    out.append(fn(s))
                    bar.update()
                    if on_result is not None:
                        on_result(out[-1])
                return out
            return self._local(fn, specs, bar, on_result)
        finally:
            bar.close()

    def _local(self, fn: Callable[[Any], Any], specs: Sequence[Any], bar: tqdm,
               on_result: Callable[[Any], None] | None) -> list[Any]:
        results: list[Any] = [None] * len(specs)
        # forkserver: children never inherit MuJoCo or socket state from this process
        ctx = multiprocessing.get_context("forkserver")
        with cf.ProcessPoolExecutor(max_workers=min(self.workers, len(specs)), mp_context=ctx) as pool:
            futures = {pool.submit(fn, s): i for i, s in enumerate(specs)}
            for fut in cf.as_completed(futures):
                results[futures[fut]] = fut.result()
                bar.update()
                if on_result is not None:
                    on_result(results[futures[fut]])
        return results

    def _dask(self, fn: Callable[[Any], Any], specs: Sequence[Any], bar: tqdm,
              on_result: Callable[[Any], None] | None) -> list[Any]:
        from distributed import Client, as_completed

        try:
            client = Client(self.scheduler, timeout="10s")
        except (OSError, TimeoutError) as exc:
            raise UserError(f"cannot reach Dask scheduler {self.scheduler}: {exc}") from None
        try:
            futures = client.map(fn, list(specs), pure=False)
            index = {f.key: i for i, f in enumerate(futures)}
            results: list[Any] = [None] * len(specs)
            for fut in as_completed(futures):
                results[index[fut.key]] = fut.result()
                bar.update()
                if on_result is not None:
                    on_result(results[index[fut.key]])
            return results
        finally:
            client.close()
