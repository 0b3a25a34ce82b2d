"""Seed 000's robot and beams as the paper describes them (Sec. II-A, Eq. 4, 8, 12).

Xuan, Wang & Li, "Environmental force sensing enables robots to traverse cluttered
obstacles with interaction" (``/work/shared/seeds/000_*.txt``):

* body: ellipsoid 2a x 2b x 2c = 0.24 x 0.14 x 0.06 m, M = 0.2 kg, CoM h_c = 0.02 m below the
  geometric centre, I = (2, 5, 7)e-3 kg m^2, centre at H = 0.06 m;
* beams: massless rigid plates, w = 0.05 m, L = 0.16 m, hinged at x = 0 on a line along y at
  height h_b, deflecting forward (positive rotation about +y) against a torsion spring k;
  Eq. 12 (robot validation) adds a beam mass M_B and a preload torque tau_0.

Gap width: ``gap_m`` is the beams' centre-to-centre spacing by default (clear gap 0.07 m);
``BodyGeometry(gap_centre_to_centre=False)`` reads d as the clear gap. docs/beams.md says why.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

G_M_S2 = 9.81


@dataclass(frozen=True)
class BodyGeometry:
    """Body and beam dimensions (Sec. II-A); defaults are the paper's simulation robot."""

    a_m: float = 0.12
    b_m: float = 0.07
    c_m: float = 0.03
    mass_kg: float = 0.2
    hc_m: float = 0.02
    inertia_kg_m2: tuple[float, float, float] = (2e-3, 5e-3, 7e-3)
    height_m: float = 0.06          # H: the geometric centre's height
    beam_width_m: float = 0.05      # w
    beam_length_m: float = 0.16     # L
    gap_m: float = 0.12             # d
    gap_centre_to_centre: bool = True

    def beam_y_range(self, beam: int) -> tuple[float, float]:
        """(y_lo, y_hi) of beam 0 (+y side) or 1 (-y side), in metres."""
        inner = self.gap_m / 2 - (self.beam_width_m / 2 if self.gap_centre_to_centre else 0.0)
        outer = inner + self.beam_width_m
        return (inner, outer) if beam == 0 else (-outer, -inner)

    def k0_nm_per_rad(self) -> float:
        """Sec. II-G critical stiffness k0 = M g h_c / arccos(H/L)^2 (0.028 in Sec. III-A)."""
        return self.mass_kg * G_M_S2 * self.hc_m / math.acos(self.height_m / self.beam_length_m) ** 2


PAPER_BODY = BodyGeometry()


@dataclass
class BeamParams:
    """One beam: stiffness (N m/rad), deflection height (m), Eq. 12 preload (N m) and mass (kg)."""

    k_nm_per_rad: float
    hb_m: float = 0.0
    preload_nm: float = 0.0
    mass_kg: float = 0.0


def beam_torque_nm(theta: float, k: float, preload_nm: float = 0.0, beam_mass_kg: float = 0.0,
                   length_m: float = 0.16) -> float:
    """Restoring torque of a deflected beam: k theta (Eq. 4) + tau_0 - (L/2) M_B g sin theta (Eq. 12).

    Eq. 12 writes the weight term as (L/2) M_B g; its moment about the hinge is really
    (L/2) M_B g sin(theta) (zero for an upright beam), which is what we use.
    """
    return max(preload_nm + k * theta - 0.5 * length_m * beam_mass_kg * G_M_S2 * math.sin(theta), 0.0)


def gravity_energy_j(roll_rad, pitch_rad, geometry: BodyGeometry = PAPER_BODY):
    """M g Z_CoM (Eq. 8's first term): the CoM sits h_c below the centre in the body frame."""
    return geometry.mass_kg * G_M_S2 * (geometry.height_m - geometry.hc_m * np.cos(roll_rad) * np.cos(pitch_rad))
