"""The papers' figures read as they should: no legend over a data point,
no wide blank bands, a path too short to see pointed out. Each draws from made-up results
and inspects the figure matplotlib drew."""
from __future__ import annotations

import random
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from hexhil.papers.beam_traversal.force_sensing import figures
from hexhil.papers.beam_traversal.force_sensing.sections import (DELAY_SERIES, DELAYS_MS,
                                                                      K_FLIMSY, K_STIFF)
from hexhil.papers.tactile_hexapod import report


@pytest.fixture
def drawn(monkeypatch):
    """The figures a call draws, kept open instead of closed."""
    import matplotlib.pyplot as plt

    kept: list = []
    monkeypatch.setattr(plt, "close", kept.append)
    return kept


def test_fig7_legends_cover_no_point(tmp_path: Path, drawn) -> None:
    runs = {}
    for i, (key, _) in enumerate(DELAY_SERIES):       # the 600 ms energies mid-height, right
        for d in DELAYS_MS:
            runs[f"{key}/{d}"] = {"control_start": {"pitch_deg": -5.0 - 3 * i - d / 100},
                                  "energy_J": 0.010 + 0.004 * i + 1e-5 * d}
    runs[f"avoid/{K_STIFF}"], runs[f"avoid/{K_FLIMSY}"] = {"energy_J": 0.012}, {"energy_J": 0.016}
    figures.fig_delay(runs, tmp_path / "fig7.png")
    fig = drawn[0]
    fig.canvas.draw()
    for ax in fig.axes:
        box = ax.get_legend().get_window_extent()
        for line in ax.lines:
            for x, y in ax.transData.transform(line.get_xydata()):
                assert not box.contains(x, y), (ax.get_ylabel(), line.get_label())


def _runs() -> list[dict]:
    rng = random.Random(1)
    return [dict(stage=stage, gait=g, density=dens, distance_m=d, height_class=h,
                 dx_m=d - rng.uniform(0, 0.3), dy_m=rng.uniform(-0.15, 0.15),
                 dyaw_deg=rng.uniform(-30, 30), error_m=rng.uniform(0, 0.3))
            for stage in ("without", "with") for g in ("tripod", "wave")
            for dens in ("low", "high") for d in (1.0, 2.0) for h in ("small", "large")
            for _ in range(2)]


def test_end_position_figures_have_no_wide_blank_bands(tmp_path: Path, drawn) -> None:
    """Fig. 16-18: the panels (equal aspect: ends lie along x within cm of y = 0) fill at
    least half the figure's height; side by side they filled a quarter."""
    paths = report.plots({"runs": _runs()}, tmp_path)
    assert [p.name for p in paths][:3] == ["fig16_without_method.png", "fig17_wave_with_method.png",
                                           "fig18_tripod_with_method.png"]
    for fig in drawn[:3]:
        fig.canvas.draw()
        rows = {(round(ax.get_position().y0, 3), round(ax.get_position().y1, 3))
                for ax in fig.axes}
        assert sum(y1 - y0 for y0, y1 in rows) > 0.5, rows


def test_gap_readings_point_out_a_path_too_short_to_see(tmp_path: Path, drawn) -> None:
    deg = np.radians(np.linspace(-90, 90, 37))
    grid = SimpleNamespace(roll_rad=deg, pitch_rad=deg, snap=lambda x, r, p: (0, 18, 18))
    land = SimpleNamespace(grid=grid, energy=lambda k1, k2: np.zeros((1, 37, 37)))

    def plan(span_deg: float, mode: str):
        t = np.radians(np.linspace(0, span_deg, 5))
        return SimpleNamespace(path=np.stack([0 * t, t if mode == "roll" else 0 * t,
                                              t if mode == "pitch" else 0 * t], 1), mode=mode)

    res = {"land": land, "plans": {K_FLIMSY: plan(3.0, "pitch"), K_STIFF: plan(70.0, "roll")}}
    figures.fig_gap_readings(res, res, tmp_path / "gap.png")
    texts = {(r, c): [t.get_text() for t in ax.texts]
             for (r, c), ax in zip(((0, 0), (0, 1), (1, 0), (1, 1)), drawn[0].axes)}
    assert texts[0, 0] == ["the whole path: within 3.0 deg"] and texts[0, 1] == []
