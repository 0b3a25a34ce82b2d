"""The force-sensing experiment's figures (PNGs): Fig. 3, 4 and 7 of seed 000 and both readings
of the gap width. matplotlib is imported only when a figure is drawn."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from hexhil.hil.world.beams import SENSOR_PERIOD_US
from hexhil.papers.beam_traversal.force_sensing.sections import (DELAY_SERIES, DELAYS_MS, K_FLIMSY, K_STIFF, NOISES,
                                                           sensed)

VMAX_MJ = 60.0                            # landscape colour scale: barriers of interest are below this
SAME_MJ = 0.05                            # reference lines closer than this print as one


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _save(fig: Any, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    _plt().close(fig)
    return path


def fig_noisy_forces(poses: np.ndarray, forces: np.ndarray, path: Path) -> Path:
    """Fig. 3: sensed contact force at 5/10/20/50 % noise (stiff beams, 1 N push, T_s = 300 ms)."""
    plt = _plt()
    t = np.arange(len(forces)) * SENSOR_PERIOD_US * 1e-3
    fig, axes = plt.subplots(1, 4, figsize=(14, 3.2), sharey=True)
    for ax, noise in zip(axes, NOISES):
        noisy = sensed(forces, noise, 0)
        for j, (lab, col) in enumerate(zip("xyz", ("C0", "C1", "C2"))):
            ax.plot(t, forces[:, j], color=col, lw=1, label=f"F{lab} noise-free")
            ax.plot(t, noisy[:, j], ".", color=col, ms=3, label=f"F{lab} sensed")
        ax.set_title(f"noise {noise:.0%}")
        ax.set_xlabel("time after contact (ms)")
    axes[0].set_ylabel("contact force (N)")
    axes[0].legend(ncol=2, fontsize=7, loc="lower right")
    return _save(fig, path)


def _path(ax: Any, xs: np.ndarray, ys: np.ndarray, label: str, ends: bool = True) -> None:
    """A planned path that stays visible however short: a white line with a dark edge, its
    start and end marked (``ends``; not where a projection folds them onto one point)."""
    from matplotlib import patheffects

    outline = [patheffects.withStroke(linewidth=4, foreground="black")]
    ax.plot(xs, ys, "w-", lw=2, path_effects=outline, label=label)
    if ends:
        ax.plot(xs[:1], ys[:1], "o", color="white", mec="black", ms=7, clip_on=False,
                label="path start")
        ax.plot(xs[-1:], ys[-1:], "s", color="white", mec="black", ms=7, clip_on=False,
                label="path end")


def fig_landscape(plan_res: dict[str, Any], path: Path) -> Path:
    """Fig. 4-like: Eq. 8 slices with the planned paths projected onto them."""
    plt = _plt()
    land = plan_res["land"]
    g = land.grid
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for ax, k, axis in ((axes[0], K_FLIMSY, 2), (axes[1], K_STIFF, 1)):
        e = land.energy(k, k)
        e = e - e.min()                  # above the level pose far from the beams
        p = plan_res["plans"][k]
        if axis == 2:       # pitch mode: the roll = 0 slice, E(x, pitch)
            sl, ang, lab = e[:, g.snap(0, 0, 0)[1], :], g.pitch_rad, "pitch (deg)"
        else:               # roll mode: the pitch = 0 slice, E(x, roll)
            sl, ang, lab = e[:, :, g.snap(0, 0, 0)[2]], g.roll_rad, "roll (deg)"
        im = ax.pcolormesh(g.x_m, np.degrees(ang), sl.T * 1e3, shading="auto", cmap="viridis",
                           vmin=0.0, vmax=VMAX_MJ)
        _path(ax, p.path[:, 0], np.degrees(p.path[:, axis]), f"planned path ({p.mode})")
        ax.set_title(f"k = {k} N m/rad: E at {'roll' if axis == 2 else 'pitch'} = 0")
        ax.set_xlabel("x (m)")
        ax.set_ylabel(lab)
        ax.legend(loc="lower left", fontsize=8)
        fig.colorbar(im, ax=ax, extend="max", label=f"E - E_min (mJ), capped at {VMAX_MJ:g}")
    return _save(fig, path)


def fig_gap_readings(c2c: dict[str, Any], clear: dict[str, Any], path: Path) -> Path:
    """Both readings of d = 0.12 m: E(roll, pitch) at x = 0 with each k's planned path projected."""
    plt = _plt()
    fig, axes = plt.subplots(2, 2, figsize=(10, 8), sharex=True, sharey=True, layout="constrained")
    for row, (name, res) in enumerate((("centre-to-centre (chosen)", c2c), ("clear gap", clear))):
        land = res["land"]
        g = land.grid
        ix = g.snap(0.0, 0, 0)[0]
        for col, k in enumerate((K_FLIMSY, K_STIFF)):
            ax = axes[row, col]
            full = land.energy(k, k)
            e = full[ix] - full.min()
            im = ax.pcolormesh(np.degrees(g.roll_rad), np.degrees(g.pitch_rad), e.T * 1e3, shading="auto",
                               cmap="viridis", vmin=0.0, vmax=VMAX_MJ)   # one range for all four
            p = res["plans"][k]
            roll_deg, pitch_deg = np.degrees(p.path[:, 1]), np.degrees(p.path[:, 2])
            _path(ax, roll_deg, pitch_deg, "planned path, projected (starts and ends level)",
                  ends=False)
            span_deg = max(np.ptp(roll_deg), np.ptp(pitch_deg))
            if span_deg < 0.1 * np.ptp(np.degrees(g.pitch_rad)):   # a tick: point it out
                ax.annotate(f"the whole path: within {span_deg:.1f} deg",
                            (roll_deg.max(), pitch_deg.max()), xytext=(0.05, 0.88), ha="left",
                            textcoords="axes fraction", color="white", fontsize=9,
                            arrowprops={"arrowstyle": "->", "color": "white", "lw": 1.5})
            ax.set_title(f"{name}, k = {k}: plans {p.mode}", fontsize=10)
            ax.set_xlabel("roll (deg)")
            ax.set_ylabel("pitch (deg)")
    axes[0, 0].legend(loc="lower left", fontsize=8)
    fig.colorbar(im, ax=axes, extend="max", shrink=0.8,
                 label=f"E - E_min at x = 0 (mJ), capped at {VMAX_MJ:g}")
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def fig_delay(runs: dict[str, Any], path: Path) -> Path:
    """Fig. 7: (A) pitch at the start of control, (B) Eq. 11 energy, against the sensory delay."""
    plt = _plt()
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.8), layout="constrained")
    for key, lab in DELAY_SERIES:
        rs = [runs[f"{key}/{d}"] for d in DELAYS_MS]
        a.plot(DELAYS_MS, [r.get("control_start", {}).get("pitch_deg", float("nan")) for r in rs], "o-", label=lab)
        b.plot(DELAYS_MS, [r["energy_J"] * 1e3 for r in rs], "o-", label=f"{lab} (interaction)")
    stiff_mj, flimsy_mj = (runs[f"avoid/{k}"]["energy_J"] * 1e3 for k in (K_STIFF, K_FLIMSY))
    if abs(stiff_mj - flimsy_mj) < SAME_MJ:   # one line would hide the other: say both
        b.axhline(stiff_mj, ls="--", color="k", label=f"avoidance, stiff and flimsy alike "
                                                      f"({stiff_mj:.1f} mJ)")
    else:
        b.axhline(stiff_mj, ls="--", color="grey", label=f"stiff avoidance ({stiff_mj:.1f} mJ)")
        b.axhline(flimsy_mj, ls=":", color="k", label=f"flimsy avoidance ({flimsy_mj:.1f} mJ)")
    a.set_xlabel("sensory delay (ms)")
    a.set_ylabel("pitch at control start (deg)")
    b.set_xlabel("sensory delay (ms)")
    b.set_ylabel("energy cost E_cost (mJ)")
    for ax in (a, b):   # below the axes: inside, a legend covered a delay's points
        ax.set_xticks(DELAYS_MS)
        ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=2)
    fig.savefig(path, dpi=90, bbox_inches="tight")
    plt.close(fig)
    return path
