"""Leg trajectory of seed 003, Eq. 2-4 (after its ref. [68]), MicroPython-compatible.

Time is in the paper's normalised units: one unit is the duration of one leg transfer
(swing), the gait period is ``T`` units and leg i lifts off at ``phi`` (0 <= phi < T).
Eq. 4's swing branch ``h sin((t - phi) pi)`` only returns to the ground at t = phi + 1,
which fixes the swing to one unit. Real time maps by ``t = T * t_s / period_s``.

Eq. 2-3 swing branch: the foot moves ``l (t - phi)`` along the walking direction epsilon,
from 0 to l. The stance branches as printed, ``-/+ (l (T - 2 phi + 2 t - 1) / (2 (T - 1))
+ l / 2)``, are not continuous with the swing (x(phi) = -l against 0) and move the foot
forward during stance. We read them as the one line that joins the swing's ends over the
remaining T - 1 units, i.e. with A(t) = l (T - 2 phi + 2 t - 1) / (2 (T - 1)):

    t <= phi:          s = l/2 - A(t)                   (from l phi / (T - 1) down to 0)
    phi < t <= phi+1:  s = l (t - phi)                  (swing, 0 to l)
    t > phi + 1:       s = l/2 - A(t) + l T / (T - 1)   (= branch 1 one period later)

and x = cos(epsilon) s, y = sin(epsilon) s. A stance foot sweeps l in T - 1 units, and some
foot is always in stance, so the body moves at l T / ((T - 1) period_s): a world-frame stride
of l T / (T - 1) per period (2 l for tripod, 1.2 l for wave).
"""
import math


def stroke(t, l, T, phi):
    """Eq. 2-3's scalar stroke s(t) (m) at normalised time 0 <= t < T."""
    if t <= phi:
        return l / 2 - l * (T - 2 * phi + 2 * t - 1) / (2 * (T - 1))
    if t <= phi + 1:
        return l * (t - phi)
    return l / 2 - l * (T - 2 * phi + 2 * t - 1) / (2 * (T - 1)) + l * T / (T - 1)


def lift(t, h, phi):
    """Eq. 4: foot height z(t) (m) above the stance plane."""
    if phi < t <= phi + 1:
        return h * math.sin((t - phi) * math.pi)
    return 0.0


def foot(t, l, h, T, phi, eps):
    """Eq. 2-4: (x, y, z) of the foot relative to its stroke origin (m)."""
    s = stroke(t, l, T, phi)
    return (math.cos(eps) * s, math.sin(eps) * s, lift(t, h, phi))


def in_swing(t, phi):
    return phi < t <= phi + 1
