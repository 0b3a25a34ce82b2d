"""Seed 003 Eq. 2-4 (firmware/trajectory.py), read as documented there."""
import math

import pytest

from hexhil.firmware import trajectory as traj

L, H = 0.05, 0.03


def A(t, T, phi, l=L):
    """The paper's printed term l (T - 2 phi + 2 t - 1) / (2 (T - 1))."""
    return l * (T - 2 * phi + 2 * t - 1) / (2 * (T - 1))


@pytest.mark.parametrize("T,phi", [(2, 0), (2, 1), (6, 0), (6, 3), (6, 5)])
def test_branches_against_the_equations(T, phi):
    for k in range(0, 600):
        t = k * T / 600
        s = traj.stroke(t, L, T, phi)
        z = traj.lift(t, H, phi)
        if t <= phi:
            assert s == pytest.approx(L / 2 - A(t, T, phi), abs=1e-12)
            assert z == 0.0
        elif t <= phi + 1:
            assert s == pytest.approx(L * (t - phi), abs=1e-12)              # Eq. 2 swing
            assert z == pytest.approx(H * math.sin((t - phi) * math.pi))     # Eq. 4 swing
        else:
            assert s == pytest.approx(L / 2 - A(t, T, phi) + L * T / (T - 1), abs=1e-12)
            assert z == 0.0


def test_eq3_and_direction():
    eps = math.radians(30)
    x, y, z = traj.foot(1.5, L, H, 6, 1, eps)
    s = traj.stroke(1.5, L, 6, 1)
    assert (x, y) == pytest.approx((math.cos(eps) * s, math.sin(eps) * s))
    assert z == pytest.approx(H)   # mid-swing: the top of Eq. 4's arc


@pytest.mark.parametrize("T,phi", [(2, 0), (2, 1), (6, 2), (6, 5)])
def test_continuous_periodic_and_constant_stance_speed(T, phi):
    eps = 1e-9
    assert traj.stroke(phi + eps, L, T, phi) == pytest.approx(0.0, abs=1e-7)   # lift-off at 0
    assert traj.stroke(phi + 1, L, T, phi) == pytest.approx(L)                  # touch-down at l
    assert traj.stroke(phi + 1 + eps, L, T, phi) == pytest.approx(L, abs=1e-7)
    assert traj.stroke(T - eps, L, T, phi) == pytest.approx(traj.stroke(0.0, L, T, phi), abs=1e-7)
    # stance: the foot moves back l over T - 1 units, at a constant rate
    ts = [phi + 1 + k * (T - 1) / 50 for k in range(1, 50)]
    rates = []
    for t in ts:
        tw = t % T
        rates.append((traj.stroke((tw + 1e-6) % T, L, T, phi) - traj.stroke(tw, L, T, phi)) / 1e-6)
    assert all(r == pytest.approx(-L / (T - 1), rel=1e-4) for r in rates)


def test_printed_stance_branches_would_be_discontinuous():
    """Why we do not take Eq. 2's stance branches literally (see the module docstring)."""
    T, phi = 6, 2
    printed_first = -(A(phi, T, phi) + L / 2)
    assert printed_first == pytest.approx(-L)           # jumps to 0 at lift-off
    assert traj.stroke(phi, L, T, phi) == pytest.approx(0.0)
