"""Seed 003's Eq. 8-14 evaluated on hand-built event logs."""
import math

import pytest

from hexhil.papers.tactile_hexapod import error_model as em


def test_alpha_k_is_eq_12_to_14():
    # dL = a gives beta = arccos(1/2) = 60 deg, so alpha_k = 180 - 2 * 60 = 60 deg
    assert math.degrees(em.alpha_k(0.3, 0.3)) == pytest.approx(60.0)
    assert em.alpha_k(0.0, 0.3) == pytest.approx(0.0)
    # small losses turn the robot by about dL / a radians
    assert em.alpha_k(0.01, 0.3) == pytest.approx(0.01 / 0.3, rel=1e-3)


def test_lateral_error_is_eq_9():
    assert em.lateral_error(1.0, 0.0, math.radians(45)) == pytest.approx(1.0)
    assert em.lateral_error(1.0, 0.2, math.radians(-10)) == pytest.approx(-0.8 * math.tan(math.radians(10)))


def _trajectory(speeds):
    """10 Hz samples of a body moving along x at the given speed in each 0.1 s interval."""
    out, x = [(0, 0.0, 0.0, 0.0)], 0.0
    for k, v in enumerate(speeds, start=1):
        x += v * 0.1
        out.append((k * 100_000, x, 0.0, 0.0))
    return out


def test_one_left_leg_caught_loses_what_the_body_lost():
    # nominal 0.1 m/s; body stands still from 1 s to 2 s while LF's switch is closed
    traj = _trajectory([0.1] * 10 + [0.0] * 10 + [0.1] * 10)
    p = em.predict([(1_000_000, 0, True), (2_000_000, 0, False)], traj, 0.1, 1.0, 0.3)
    assert p.hits == 1
    assert p.dx_m == pytest.approx(0.1)                        # Eq. 8
    assert p.dalpha_rad == pytest.approx(em.alpha_k(0.1, 0.3))  # left leg: turns left, positive
    assert p.remaining_m == pytest.approx(1.0 - 0.1 * 2.0)      # Eq. 10 at the last release
    assert p.dy_m == pytest.approx(em.lateral_error(0.8, 0.1, p.dalpha_rad))
    assert p.dy_m > 0


def test_legs_caught_together_share_the_loss_and_opposite_sides_cancel():
    traj = _trajectory([0.1] * 10 + [0.0] * 10)
    events = [(1_000_000, 0, True), (1_000_000, 3, True), (2_000_000, 0, False), (2_000_000, 3, False)]
    p = em.predict(events, traj, 0.1, 1.0, 0.3)
    assert p.hits == 2
    assert p.lost_m == pytest.approx([0.05, 0.05])
    assert p.dx_m == pytest.approx(0.1)
    assert p.dalpha_rad == pytest.approx(0.0)
    assert p.dy_m == pytest.approx(0.0)


def test_no_events_no_error_and_unreleased_switch_counts_to_the_end():
    traj = _trajectory([0.1] * 10 + [0.02] * 10)
    assert em.predict([], traj, 0.1, 1.0, 0.3).dx_m == 0.0
    p = em.predict([(1_000_000, 4, True)], traj, 0.1, 1.0, 0.3)
    assert p.dx_m == pytest.approx(0.08)
    assert p.dalpha_rad < 0  # a right leg turns the robot right
