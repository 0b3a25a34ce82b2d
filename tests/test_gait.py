"""Gait phase tables (seed 003 Fig. 13, protocol/hexapod.py) and the gait clock (firmware/gait.py)."""
import pytest

from hexhil.firmware import gait as g
from hexhil.firmware import trajectory as traj
from hexhil.protocol import hexapod

LEGS = ("LF", "LM", "LH", "RF", "RM", "RH")


def swinging(name, t):
    T, phases = hexapod.GAITS[name]
    return {LEGS[i] for i in range(6) if traj.in_swing(t, phases[i])}


def test_tripod_groups_fig13():
    assert swinging("tripod", 0.5) == {"LM", "RF", "RH"}      # first half of the period
    assert swinging("tripod", 1.5) == {"LF", "LH", "RM"}      # second half


def test_wave_order_fig13():
    order = [swinging("wave", k + 0.5) for k in range(6)]
    assert order == [{"LF"}, {"LM"}, {"LH"}, {"RF"}, {"RM"}, {"RH"}]


@pytest.mark.parametrize("name,n", [("tripod", 3), ("wave", 1)])
def test_legs_in_transfer_at_any_time(name, n):
    T = hexapod.GAITS[name][0]
    for k in range(1, 1000):
        assert len(swinging(name, k * T / 1000)) == n


def test_speed_matches_paper_at_default_periods():
    for name, v in (("tripod", 0.036), ("wave", 0.013)):
        assert hexapod.speed_m_s(name, 0.05, hexapod.GAIT_PERIOD_S[name]) == pytest.approx(v)


def test_clock_and_change_only_at_wrap():
    clk = g.Gait("tripod", 2.0, t0_us=0)
    clk.advance(500_000)
    assert clk.t == pytest.approx(0.5)
    clk.request("wave", 6.0)
    clk.advance(1_500_000)
    assert clk.name == "tripod" and clk.t == pytest.approx(1.5)   # not mid-period
    assert clk.advance(2_020_000)                                 # wrapped
    assert clk.name == "wave" and clk.T == 6 and clk.period_us == 6_000_000
    assert clk.t == pytest.approx(0.0)
    with pytest.raises(ValueError):
        clk.request("gallop", 1.0)
