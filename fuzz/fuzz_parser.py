"""The Protocol 1.0 stream parser: on the host, and the firmware's code path under the
real ``micropython`` binary, which must print the same digests as CPython."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from fuzz.hostile import run_parser
from fuzz.tally import Budget, Tally

ROOT = Path(__file__).resolve().parent.parent
BATCH = 2000           # inputs a budget check
MPY_SHARE = 0.05       # of the host's inputs, replayed under micropython
REPORT_EVERY = 500


def run(seed: int, budget_s: float | None, limit: int | None) -> list[Tally]:
    host = Tally("protocol parser (CPython)", "streams")
    budget = Budget(budget_s, limit)
    batch = 0
    while budget.more(host.inputs):
        n = BATCH if limit is None else min(BATCH, limit - host.inputs)
        count, nbytes, escaped, found, _ = run_parser(seed * 100_003 + batch, n)
        batch += 1
        host.inputs += count
        host.notes["bytes"] = host.notes.get("bytes", 0) + nbytes
        host.resync_checked += count
        host.resync_found += found
        if escaped:
            host.escape(f"parser raised on seed {seed * 100_003 + batch - 1}")
    host.wall_s = budget.elapsed_s()
    return [host, micropython_agrees(seed, max(REPORT_EVERY, int(host.inputs * MPY_SHARE)))]


def _python_for(interpreter: str) -> list[str]:
    if interpreter == "micropython":
        return [str(Path(sys.executable).parent / "micropython")]
    return [sys.executable]


def micropython_agrees(seed: int, count: int) -> Tally:
    """``count`` streams through the parser under micropython and CPython: same digests."""
    tally = Tally("protocol parser (MicroPython = CPython)", "streams")
    env = dict(os.environ, MICROPYPATH=str(ROOT), PYTHONPATH=str(ROOT))
    args = [str(ROOT / "fuzz" / "mpy_parser.py"), str(seed), str(count), str(REPORT_EVERY)]
    outs = []
    t0 = __import__("time").perf_counter()
    for interpreter in ("micropython", "cpython"):
        proc = subprocess.run(_python_for(interpreter) + args, cwd=ROOT, env=env,
                              capture_output=True, text=True, timeout=3600)
        if proc.returncode:
            tally.escape(f"{interpreter}: {proc.stderr.strip().splitlines()[-1:]}")
        outs.append(proc.stdout.splitlines())
    tally.wall_s = __import__("time").perf_counter() - t0
    mpy, cpy = outs
    tally.inputs = count
    done = [line.split() for line in mpy if line.startswith("DONE")]
    if done:
        tally.resync_checked = count
        tally.resync_found = int(done[0][4])
        tally.escaped += int(done[0][3])
    if mpy != cpy:
        first = next((i for i, (a, b) in enumerate(zip(mpy, cpy)) if a != b), len(mpy))
        tally.escape(f"micropython and CPython differ at digest line {first}")
    return tally
