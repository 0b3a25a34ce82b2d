"""Debounce and the Eq. 5-7 switching rule (firmware/tactile.py)."""
import pytest

from hexhil.firmware import tactile


def test_debounce_needs_consecutive_samples():
    sw = tactile.Switches(samples=2)
    assert sw.update(0b1) == 0          # one sample: a bounce
    assert sw.update(0b0) == 0
    assert sw.update(0b1) == 0
    assert sw.update(0b1) == 0b1        # held for two samples
    assert sw.state == 0b1 and sw.edges == 1
    assert sw.update(0b0) == 0 and sw.update(0b0) == 0b1 and sw.state == 0


def test_eq6_eq7_values():
    r = tactile.ObstacleRule(0.05, 0.03, 0.05)
    assert r.l_k == pytest.approx(0.10)          # Eq. 6: 2 l_i
    assert r.h_k == pytest.approx(0.07)          # Eq. 7: H + 2 cm


def test_switch_mid_swing_changes_parameters_only_at_next_lift_off():
    r = tactile.ObstacleRule(0.05, 0.03, 0.05)
    leg = 2
    assert not r.lift_off(leg, 0)                # a normal step starts
    assert r.l[leg] == 0.05
    r.touched(1 << leg)                          # the switch fires mid-swing
    assert r.l[leg] == 0.05 and r.h[leg] == 0.03 and r.overcoming == 0   # unchanged
    assert r.lift_off(leg, 0)                    # next step: the obstacle trajectory
    assert (r.l[leg], r.h[leg]) == pytest.approx((0.10, 0.07))
    assert r.overcoming == 1 << leg
    assert r.lift_off(leg, 0)                    # a step without contact: back to initial
    assert (r.l[leg], r.h[leg]) == (0.05, 0.03) and r.overcoming == 0
    assert r.changes == 2 and r.steps == 3


def test_other_legs_unaffected_and_pressed_at_lift_off_counts():
    r = tactile.ObstacleRule(0.05, 0.03, 0.08)
    r.touched(0b000001)
    r.lift_off(3, 0)
    assert r.l[3] == 0.05                       # leg 3 never touched
    r.lift_off(4, 1 << 4)                       # still pressed at lift-off
    assert r.h[4] == pytest.approx(0.10)


def test_rule_disabled_is_the_baseline():
    r = tactile.ObstacleRule(0.05, 0.03, 0.05, enabled=False)
    r.touched(0b111111)
    assert not r.lift_off(0, 1)
    assert r.l[0] == 0.05 and r.overcoming == 0
