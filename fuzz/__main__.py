"""``make fuzz``: every fuzz target for its default budget, one table, exit 1 on any escape.

Usage: python -m fuzz [--seed N] [--scale X] [--budget-s S] [target ...]
The default budget is a number of inputs per target (``DEFAULT_INPUTS``), the issue's
1,000,000 parser streams and 200,000 emulator streams; ``--scale`` multiplies it and
``--budget-s`` caps each target's wall time instead. Targets run in parallel processes,
one per core.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys
from concurrent.futures import ProcessPoolExecutor

from fuzz.tally import Tally

DEFAULT_INPUTS = {"parser": 1_000_000, "bus": 200_000, "can": 200_000, "scenario": 20_000,
                  "trace": 2_000}


def run_target(name: str, seed: int, budget_s: float | None, limit: int | None) -> list[Tally]:
    return importlib.import_module(f"fuzz.fuzz_{name}").run(seed, budget_s, limit)


def table(tallies: list[Tally]) -> str:
    """The figures as a plain-text table."""
    head = f"{'target':<42} {'inputs':>10} {'unit':<9} {'per s':>8} {'escaped':>7} {'resync':>8}"
    rows = [head, "-" * len(head)]
    for t in tallies:
        resync = "-" if t.resync_pct is None else f"{t.resync_pct:.2f}%"
        rows.append(f"{t.target:<42} {t.inputs:>10,} {t.unit:<9} {t.rate_per_s:>8,.0f} "
                    f"{t.escaped:>7} {resync:>8}")
        if t.first_escape:
            rows.append(f"    first: {t.first_escape[:200]}")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m fuzz", description=__doc__.splitlines()[0])
    p.add_argument("targets", nargs="*", choices=[[], *DEFAULT_INPUTS], default=[])
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--scale", type=float, default=1.0, help="multiply the default input counts")
    p.add_argument("--budget-s", type=float, default=None, help="wall-time cap per target")
    args = p.parse_args(argv)
    names = args.targets or list(DEFAULT_INPUTS)
    with ProcessPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
        futures = [pool.submit(run_target, n, args.seed, args.budget_s,
                               max(1, int(DEFAULT_INPUTS[n] * args.scale))) for n in names]
        tallies = [t for f in futures for t in f.result()]
    print(table(tallies))
    bad = [t for t in tallies if t.escaped or (t.resync_pct is not None and t.resync_pct < 100)]
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
