"""Sec. II-G/H: the less costly mode, and the minimal-cost path over the Eq. 8 landscape.

Every grid state is a vertex joined to its 6 neighbours (x +- dx, roll +- d, pitch +- d) by
directed edges whose cost is the energy increase (zero downhill: actuators do no work there).
Dijkstra (scipy.sparse.csgraph) runs from the state after the sensory delay to the level pose
past the beams; the path is timed at 0.02 s a vertex and fitted with 5th-order polynomials.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from hexhil.papers.beam_traversal.landscape import Landscape

VERTEX_DT_S = 0.02      # Sec. II-H: 0.02 s between path vertices
POLY_ORDER = 5          # Sec. II-H: three 5th-order polynomials
_EPS_J = 1e-12          # keeps zero-cost edges explicit and prefers shorter paths among equals


@dataclass
class Plan:
    mode: str                    # "pitch" or "roll"
    path: np.ndarray             # (n, 3) states x_m, roll_rad, pitch_rad
    energy_j: np.ndarray         # E along the path
    path_cost_j: float           # sum of positive energy increases
    barrier_j: float             # max E along the path minus E at the start
    coeffs: np.ndarray           # (3, POLY_ORDER + 1) in normalised time tau = t / duration
    duration_s: float

    def desired(self, t_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q_d, q_d dot, q_d ddot) at t_s after the plan starts; held at the end."""
        tau = min(max(t_s / self.duration_s, 0.0), 1.0)
        q = np.array([np.polyval(c, tau) for c in self.coeffs])
        if t_s >= self.duration_s:
            return q, np.zeros(3), np.zeros(3)
        d1 = np.array([np.polyval(np.polyder(c), tau) for c in self.coeffs]) / self.duration_s
        d2 = np.array([np.polyval(np.polyder(c, 2), tau) for c in self.coeffs]) / self.duration_s ** 2
        return q, d1, d2


def edge_graph(energy: np.ndarray) -> csr_matrix:
    """6-neighbour directed graph; edge cost = max(E[to] - E[from], 0) (+ a tiny epsilon)."""
    shape = energy.shape
    idx = np.arange(energy.size).reshape(shape)
    rows, cols, data = [], [], []
    for axis in range(3):
        a = [slice(None)] * 3
        b = [slice(None)] * 3
        a[axis], b[axis] = slice(0, -1), slice(1, None)
        u, v = idx[tuple(a)].ravel(), idx[tuple(b)].ravel()
        du = energy[tuple(b)].ravel() - energy[tuple(a)].ravel()
        rows += [u, v]
        cols += [v, u]
        data += [np.maximum(du, 0.0) + _EPS_J, np.maximum(-du, 0.0) + _EPS_J]
    return csr_matrix((np.concatenate(data), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(energy.size, energy.size))


def classify(path: np.ndarray) -> str:
    """Roll mode when the path rolls further than it pitches, else pitch mode."""
    return "roll" if np.abs(path[:, 1]).max() > np.abs(path[:, 2]).max() else "pitch"


def plan(land: Landscape, k1: float, k2: float, start: tuple[float, float, float],
         goal_x_m: float | None = None) -> Plan:
    """Minimal-cost path from ``start`` (x_m, roll_rad, pitch_rad) to the level pose at goal_x_m."""
    g = land.grid
    energy = land.energy(k1, k2)
    src = np.ravel_multi_index(g.snap(*start), g.shape)
    dst = np.ravel_multi_index(g.snap(g.x_m[-1] if goal_x_m is None else goal_x_m, 0.0, 0.0), g.shape)
    dist, pred = dijkstra(edge_graph(energy), directed=True, indices=src, return_predecessors=True)
    order = [dst]
    while order[-1] != src:
        order.append(pred[order[-1]])
        if order[-1] < 0:
            raise RuntimeError("goal unreachable on the landscape grid")
    order.reverse()
    ii = np.unravel_index(np.array(order), g.shape)
    path = np.stack([g.x_m[ii[0]], g.roll_rad[ii[1]], g.pitch_rad[ii[2]]], axis=1)
    e = energy.ravel()[order]
    duration = VERTEX_DT_S * (len(order) - 1)
    tau = np.linspace(0.0, 1.0, len(order))
    coeffs = np.array([np.polyfit(tau, path[:, j], POLY_ORDER) for j in range(3)])
    cost = float(np.maximum(np.diff(e), 0.0).sum())
    return Plan(classify(path), path, e, cost, float(e.max() - e[0]), coeffs, max(duration, VERTEX_DT_S))


def crossover_k(land: Landscape, start: tuple[float, float, float], lo: float = 0.002,
                hi: float = 1.0, iterations: int = 10) -> float:
    """The landscape's own pitch/roll crossover stiffness (k1 = k2), by bisection in log k."""
    if plan(land, lo, lo, start).mode == plan(land, hi, hi, start).mode:
        raise RuntimeError("no pitch/roll crossover in the stiffness range")
    mode_lo = plan(land, lo, lo, start).mode
    for _ in range(iterations):
        mid = float(np.sqrt(lo * hi))
        if plan(land, mid, mid, start).mode == mode_lo:
            lo = mid
        else:
            hi = mid
    return float(np.sqrt(lo * hi))


def critical_push_n(land: Landscape, k1: float, k2: float, start: tuple[float, float, float],
                    kinetic_j: float = 0.0, hi_n: float = 2.0, iterations: int = 30) -> float:
    """Least constant push F_x (N) that can carry the undamped body from ``start`` to the level
    pose past the beams (Sec. III-A's runs without control).

    With no damping and no torques, T + E - F_x x is conserved (Eq. 1-3 with Eq. 8's forces), so
    the body can only reach states where E - F_x x stays below its start value plus the kinetic
    energy: passage needs start and goal connected (6 neighbours, as the planner's graph) inside
    that set. Bisection on F_x; ``hi_n`` when even that does not connect them.
    """
    from scipy import ndimage

    g = land.grid
    energy = land.energy(k1, k2)
    src, dst = g.snap(*start), g.snap(g.x_m[-1], 0.0, 0.0)
    x = g.x_m[:, None, None]

    def passable(fx_n: float) -> bool:
        u = energy - fx_n * x
        labels, _ = ndimage.label(u <= u[src] + kinetic_j)
        return labels[src] == labels[dst]

    lo, hi = 0.0, hi_n
    if not passable(hi):
        return hi
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if passable(mid) else (mid, hi)
    return hi
