"""``make fuzz``: every fuzz target for its default budget, one table, exit 1 on any escape.

Usage: python -m fuzz [--seed N] [--scale X] [--budget-s S] [--phase P] [target ...]
Two phases. The seeded generators (``fuzz/fuzz_*.py``) run ``DEFAULT_INPUTS`` inputs per
target; the coverage-guided phase runs each target of ``fuzz/cov_targets.py`` under atheris
(libFuzzer) for ``COVERAGE_RUNS`` inputs. Together they make the issue's 1,000,000 parser
streams and 200,000 emulator streams. ``--scale`` multiplies both; ``--budget-s`` caps each
generator target's wall time instead. Targets run in parallel processes, one per core.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys
from concurrent.futures import Future, ProcessPoolExecutor

from fuzz import cov
from fuzz.tally import Tally

DEFAULT_INPUTS = {"parser": 900_000, "bus": 180_000, "can": 200_000, "scenario": 20_000,
                  "trace": 2_000, "parser2": 300_000, "bus2": 40_000, "elf": 20_000,
                  "logs": 500}
COVERAGE_RUNS = {"parser": 100_000, "bus": 20_000, "can": 100_000, "scenario": 20_000,
                 "trace": 2_000, "parser2": 50_000, "bus2": 10_000, "elf": 10_000,
                 "logs": 500}
PHASES = ("all", "generators", "coverage")


def run_target(name: str, seed: int, budget_s: float | None, limit: int | None) -> list[Tally]:
    return importlib.import_module(f"fuzz.fuzz_{name}").run(seed, budget_s, limit)


def table(tallies: list[Tally]) -> str:
    """The figures as a plain-text table (edges/features: what libFuzzer reached)."""
    head = (f"{'target':<42} {'inputs':>10} {'unit':<9} {'per s':>8} {'escaped':>7} "
            f"{'resync':>8} {'edges/features':>15}")
    rows = [head, "-" * len(head)]
    for t in tallies:
        resync = "-" if t.resync_pct is None else f"{t.resync_pct:.2f}%"
        cov_ft = f"{t.notes['cov']:,}/{t.notes['ft']:,}" if "cov" in t.notes else "-"
        rows.append(f"{t.target:<42} {t.inputs:>10,} {t.unit:<9} {t.rate_per_s:>8,.0f} "
                    f"{t.escaped:>7} {resync:>8} {cov_ft:>15}")
        if t.first_escape:
            rows.append(f"    first: {t.first_escape[:4000]}")
    return "\n".join(rows)


def totals(tallies: list[Tally]) -> str:
    """The issue's two figures, both phases added up."""
    def inputs(*labels: str) -> int:
        return sum(t.inputs for t in tallies if t.target in labels)
    parser = inputs("protocol parser (CPython)", cov.TARGETS["parser"].label)
    bus = inputs("emulated bus, 18 servos", cov.TARGETS["bus"].label)
    parser2 = inputs("protocol 2.0 parser (CPython)", cov.TARGETS["parser2"].label)
    bus2 = inputs("protocol 2.0 bus, 18 XL430s", cov.TARGETS["bus2"].label)
    escaped = sum(t.escaped for t in tallies)
    return (f"parser streams {parser:,} (issue: 1,000,000), emulator streams {bus:,} "
            f"(issue: 200,000); Protocol 2.0: parser streams {parser2:,}, emulator streams "
            f"{bus2:,}; escaped {escaped}")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m fuzz", description=__doc__.splitlines()[0])
    p.add_argument("targets", nargs="*", choices=[[], *DEFAULT_INPUTS], default=[])
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--scale", type=float, default=1.0, help="multiply the default input counts")
    p.add_argument("--budget-s", type=float, default=None, help="wall-time cap per target")
    p.add_argument("--phase", choices=PHASES, default="all")
    args = p.parse_args(argv)
    names = args.targets or list(DEFAULT_INPUTS)
    cov_jobs: dict[str, Future] = {}
    gen_jobs: dict[str, Future] = {}
    with ProcessPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
        if args.phase != "generators":  # the longer runs first, so the pool ends together
            cov_jobs = {n: pool.submit(cov.run, n, args.seed,
                                       max(1, int(COVERAGE_RUNS[n] * args.scale)))
                        for n in names}
        if args.phase != "coverage":
            gen_jobs = {n: pool.submit(run_target, n, args.seed, args.budget_s,
                                       max(1, int(DEFAULT_INPUTS[n] * args.scale)))
                        for n in names}
        tallies = []
        for n in names:  # both phases' rows of a target together
            tallies += gen_jobs[n].result() if n in gen_jobs else []
            tallies += [cov_jobs[n].result()] if n in cov_jobs else []
    print(table(tallies))
    print(totals(tallies))
    bad = [t for t in tallies if t.escaped or (t.resync_pct is not None and t.resync_pct < 100)]
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
