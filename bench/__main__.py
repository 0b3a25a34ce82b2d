"""``make bench``: run every ``bench/bench_*.py`` and print one table.

Each module exposes ``run() -> list[Row]``. Figures are measured in this process;
targets are the goals, shown beside them, never asserted.
"""
from __future__ import annotations

import importlib
import pkgutil
import sys
import time

from bench import Row


def main() -> int:
    import bench

    only = sys.argv[1:]
    rows: list[Row] = []
    failed = []
    for info in sorted(pkgutil.iter_modules(bench.__path__), key=lambda m: m.name):
        if not info.name.startswith("bench_"):
            continue
        if only and not any(o in info.name for o in only):
            continue
        t0 = time.perf_counter()
        try:
            mod = importlib.import_module(f"bench.{info.name}")
            rows.extend(mod.run())
        except Exception as exc:  # keep the other areas' figures; say which one broke
            failed.append(f"{info.name}: {type(exc).__name__}: {exc}")
            print(f"# {info.name} FAILED: {failed[-1]}", file=sys.stderr, flush=True)
            continue
        print(f"# {info.name}: {time.perf_counter() - t0:.1f} s", file=sys.stderr, flush=True)
    width = max((len(r.name) for r in rows), default=10)
    print(f"{'benchmark':<{width}}  {'value':>14}  {'unit':<12}  {'target':<16}  note")
    print("-" * (width + 60))
    for r in rows:
        v = f"{r.value:,.3f}" if abs(r.value) < 1000 else f"{r.value:,.0f}"
        print(f"{r.name:<{width}}  {v:>14}  {r.unit:<12}  {r.target:<16}  {r.note}")
    for f in failed:
        print(f"FAILED {f}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
