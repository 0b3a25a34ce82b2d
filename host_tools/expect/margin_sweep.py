"""``hexhil margin``: where a firmware's expectations stop holding as the bus's timing gets
worse. In lockstep, each setting is one run of the case (host_tools/expect/case_runs.py) with one
thing changed on the simulated bus (hil/servobus/line.py's margin hooks, or the scenario's faults):

* ``return_delay_us``: the servos answer this long after a packet, whatever register 5 holds
  (the firmware writes 0 there at configure; a servo that keeps its delay is what this is);
* ``adapter_latency_us``: received bytes reach the master this much later (the USB-serial
  adapter's latency timer, 1-16 ms on an FTDI, set with ``setserial``/``latency_timer``);
* ``bit_error_rate``: bits flipped on the line, both ways;
* ``baud_error_pct``: the master's UART runs this much off the servos' 1 Mbps.

Return Delay and latency are also swept together (the heat map): both delay the reply the
master waits for. Results: every point's outcomes and the first failing setting of each axis.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Sequence

from hexhil.expect.case_runs import BusTiming, CaseResult, CaseRun, run_all
from hexhil.expect.spec import Case
from hexhil.progress import Progress

AXES: dict[str, tuple[float, ...]] = {
    "return_delay_us": (0, 40, 80, 100, 120, 160, 250, 500),
    "adapter_latency_us": (0, 40, 80, 100, 120, 1000, 2000, 4000, 8000, 16000),
    "bit_error_rate": (0.0, 1e-5, 1e-4, 1e-3, 3e-3, 1e-2),
    "baud_error_pct": (0.0, -2.0, 2.0, -4.0, 4.0, -5.0, 5.0, -6.0, 6.0),
}
GRID_RETURN_DELAY_US = (0, 40, 80, 100, 120, 160)
GRID_LATENCY_US = (0, 20, 60, 100, 1000, 16000)


@dataclass(frozen=True)
class Point:
    """One setting: the axis values changed from nominal and what the run showed."""

    settings: tuple[tuple[str, float], ...]
    passed: int
    total: int
    failed: tuple[str, ...]      # names of the expectations that did not hold
    measured: tuple[str, ...]    # the first failed one's measured value, if any

    @property
    def holds(self) -> bool:
        return self.passed == self.total


@dataclass(frozen=True)
class Margin:
    axes: dict[str, list[Point]]                  # one sweep an axis, in axis order
    grid: list[Point]                             # return delay x latency
    grid_axes: tuple[tuple[float, ...], tuple[float, ...]]

    def nominal_holds(self) -> bool:
        """Whether the expectations hold at nominal timing (every setting 0: the scenario's
        own bus): where they do not, no setting has a margin to measure."""
        return all(p.holds for points in (*self.axes.values(), self.grid) for p in points
                   if not any(v for _, v in p.settings))

    def first_failing(self) -> dict[str, float | None]:
        """Per axis, the nominal-nearest setting that fails (None: every setting held)."""
        out: dict[str, float | None] = {}
        for axis, points in self.axes.items():
            bad = [dict(p.settings)[axis] for p in points if not p.holds]
            out[axis] = min(bad, key=abs) if bad else None
        return out


def _job(case: Case, python: str, settings: dict[str, float], label: str,
         firmware: str | None = None) -> CaseRun:
    """The case's run with ``settings`` applied: bus hooks, or the scenario's faults."""
    baud = case.scenario.bus.baud
    timing = BusTiming(
        return_delay_us=int(settings["return_delay_us"]) if "return_delay_us" in settings
        else None,
        adapter_latency_us=int(settings.get("adapter_latency_us", 0)),
        master_baud=round(baud * (1 + settings["baud_error_pct"] / 100))
        if settings.get("baud_error_pct") else None)
    scenario = None
    changed: tuple[tuple[str, float], ...] = ()
    if settings.get("bit_error_rate"):
        scenario = case.scenario.overlay(
            {"faults": {"bit_error_rate": settings["bit_error_rate"]}})
        changed = (("faults.bit_error_rate", settings["bit_error_rate"]),)
    return CaseRun(case, case.seed, label, python=python, timing=timing, scenario=scenario,
                   changed=changed, firmware=firmware)


def _point(settings: dict[str, float], r: CaseResult) -> Point:
    failed = [o for o in r.outcomes if not o.passed]
    return Point(tuple(settings.items()), len(r.outcomes) - len(failed), len(r.outcomes),
                 tuple(o.name for o in failed), tuple(o.measured for o in failed[:1]))


def sweep(case: Case, python: str, axes: dict[str, Sequence[float]] | None = None,
          grid: tuple[Sequence[float], Sequence[float]] | None = None, workers: int = 1,
          scheduler: str | None = None, progress: Progress | None = None,
          firmware: str | None = None) -> Margin:
    """Every axis's settings alone, and the Return Delay x latency grid, in parallel;
    ``firmware`` (a MicroPython main file, an executable or an ELF) runs in place of the
    case's firmware."""
    axes = {k: tuple(v) for k, v in (axes or AXES).items()}
    rd, lat = grid or (GRID_RETURN_DELAY_US, GRID_LATENCY_US)
    settings: list[dict[str, float]] = [{axis: v} for axis, values in axes.items()
                                        for v in values]
    settings += [{"return_delay_us": a, "adapter_latency_us": b} for a in rd for b in lat]
    jobs = [_job(case, python, s, f"{case.name} " + ", ".join(f"{k}={v:g}" for k, v in s.items()),
                 firmware) for s in settings]
    results = run_all(jobs, workers, scheduler, progress)
    points = [_point(s, r) for s, r in zip(settings, results)]
    n_axes = sum(len(v) for v in axes.values())
    by_axis: dict[str, list[Point]] = {axis: [] for axis in axes}
    for p in points[:n_axes]:
        by_axis[p.settings[0][0]].append(p)
    return Margin(by_axis, points[n_axes:], (tuple(rd), tuple(lat)))


# The share of expectations that held, in bands: only 100 % is green, so a setting where
# one expectation of five fails (80 %) does not read as a pass.
SHARE_BANDS = (0.0, 0.5, 0.8, 0.9999, 1.0001)
SHARE_COLOURS = ("#d73027", "#fc8d59", "#fee08b", "#1a9850")   # <50 %, <80 %, <100 %, 100 %


def share_colouring() -> tuple[Any, Any]:
    """(colour map, norm) of the heat map: ``SHARE_COLOURS`` over ``SHARE_BANDS``."""
    from matplotlib.colors import BoundaryNorm, ListedColormap

    return ListedColormap(SHARE_COLOURS), BoundaryNorm(SHARE_BANDS, len(SHARE_COLOURS))


def heat_map(m: Margin, path: str, title: str) -> None:
    """The PNG: Return Delay x latency (share of expectations that held), and each axis."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    rd, lat = m.grid_axes
    share = np.array([[p.passed / max(1, p.total) for p in m.grid[i * len(lat):(i + 1) * len(lat)]]
                      for i in range(len(rd))])
    fig, axes = plt.subplots(1, 1 + len(m.axes), figsize=(4.2 + 2.0 * len(m.axes), 4.2),
                             gridspec_kw={"width_ratios": [3] + [1] * len(m.axes)})
    ax = axes[0]
    cmap, norm = share_colouring()
    im = ax.imshow(share, cmap=cmap, norm=norm, origin="lower", aspect="auto")
    ax.set_xticks(range(len(lat)), [f"{v:g}" for v in lat], rotation=45)
    ax.set_yticks(range(len(rd)), [f"{v:g}" for v in rd])
    ax.set_xlabel("adapter latency (us)")
    ax.set_ylabel("servo Return Delay (us)")
    for i in range(len(rd)):
        for j in range(len(lat)):
            ax.text(j, i, f"{share[i, j]:.0%}", ha="center", va="center", fontsize=7)
    ax.set_title("expectations holding")
    for ax, (axis, points) in zip(axes[1:], m.axes.items()):
        points = sorted(points, key=lambda p: p.settings[0][1])
        col = np.array([[p.passed / max(1, p.total)] for p in points])
        ax.imshow(col, cmap=cmap, norm=norm, origin="lower", aspect="auto")
        ax.set_yticks(range(len(points)), [f"{p.settings[0][1]:g}" for p in points])
        ax.set_xticks([])
        ax.set_title(axis.replace("_", " "), fontsize=8)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    bar = fig.colorbar(im, ax=list(axes), shrink=0.8, pad=0.02,
                       ticks=[0.25, 0.65, 0.9, 1.0])
    bar.ax.set_yticklabels(["< 50 %", "50-80 %", "80-99 %", "all"], fontsize=7)
    bar.set_label("expectations holding", fontsize=8)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def to_json(m: Margin) -> dict[str, Any]:
    return {"axes": {a: [dataclasses.asdict(p) for p in ps] for a, ps in m.axes.items()},
            "grid": [dataclasses.asdict(p) for p in m.grid],
            "first_failing": m.first_failing()}
