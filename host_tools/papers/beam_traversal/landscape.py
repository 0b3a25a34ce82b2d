"""Eq. 8 potential-energy landscape E(x, roll, pitch) on the paper's grid (Sec. II-F).

x from -0.12 to 0.12 m in 2 mm; roll and pitch from -90 to 90 deg in 2 deg (121 x 91 x 91,
about 1.0 M states). The beam deflections theta_i(x, roll, pitch) are pure geometry, so they
are computed once (vectorised, exact) and E for any stiffness is a cheap combination:
E = M g Z_CoM + k1 theta1^2 / 2 + k2 theta2^2 / 2.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hexhil.hil.world.beam_body import PAPER_BODY, BodyGeometry, gravity_energy_j
from hexhil.hil.world.beam_contact import deflection_angles


@dataclass(frozen=True)
class Grid:
    x_m: np.ndarray
    roll_rad: np.ndarray
    pitch_rad: np.ndarray

    @property
    def shape(self) -> tuple[int, int, int]:
        return len(self.x_m), len(self.roll_rad), len(self.pitch_rad)

    def snap(self, x_m: float, roll_rad: float, pitch_rad: float) -> tuple[int, int, int]:
        """Nearest grid vertex (indices) to a state."""
        return tuple(int(np.clip(np.argmin(np.abs(axis - v)), 0, len(axis) - 1))
                     for axis, v in ((self.x_m, x_m), (self.roll_rad, roll_rad), (self.pitch_rad, pitch_rad)))


def paper_grid(dx_m: float = 0.002, dangle_deg: float = 2.0, x_max_m: float = 0.12,
               angle_max_deg: float = 90.0) -> Grid:
    """Sec. II-F grid (defaults); coarser steps for quick tests."""
    nx = int(round(2 * x_max_m / dx_m)) + 1
    na = int(round(2 * angle_max_deg / dangle_deg)) + 1
    ang = np.radians(np.linspace(-angle_max_deg, angle_max_deg, na))
    return Grid(np.linspace(-x_max_m, x_max_m, nx), ang, ang.copy())


@dataclass
class Landscape:
    grid: Grid
    theta1_rad: np.ndarray
    theta2_rad: np.ndarray
    gravity_j: np.ndarray
    geometry: BodyGeometry

    def energy(self, k1: float, k2: float) -> np.ndarray:
        """Eq. 8 in joules over the grid."""
        return self.gravity_j + 0.5 * k1 * self.theta1_rad ** 2 + 0.5 * k2 * self.theta2_rad ** 2


def build(grid: Grid, hb1_m: float = 0.0, hb2_m: float = 0.0,
          geometry: BodyGeometry = PAPER_BODY) -> Landscape:
    """Deflection fields of both beams on the grid.

    Beam 2 is beam 1 mirrored in y, i.e. at the opposite roll: with equal h_b and a grid
    symmetric in roll, its field is beam 1's with the roll axis reversed (half the work).
    """
    X, R, P = np.meshgrid(grid.x_m, grid.roll_rad, grid.pitch_rad, indexing="ij")
    th1 = deflection_angles(X, R, P, hb1_m, 0, geometry)
    if hb1_m == hb2_m and np.allclose(grid.roll_rad, -grid.roll_rad[::-1]):
        th2 = th1[:, ::-1, :].copy()
    else:
        th2 = deflection_angles(X, R, P, hb2_m, 1, geometry)
    grav = np.broadcast_to(gravity_energy_j(R[0:1], P[0:1], geometry), X.shape)
    return Landscape(grid, th1, th2, grav, geometry)
