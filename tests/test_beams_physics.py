"""Seed 000 beams world: exact contact geometry vs brute force, dynamics, no-control outcomes."""
import math

import numpy as np
import pytest

from hexhil.hil.world.beam_body import PAPER_BODY, BeamParams, gravity_energy_j
from hexhil.hil.world.beam_contact import deflection_angle, deflection_angles, unit_contact_forces
from hexhil.hil.world.beams import SENSOR_PERIOD_US, BeamsWorld, external_forces

G = PAPER_BODY


def brute_theta(x, roll, pitch, hb, beam, n_s=160, n_t=40, n_theta=1571):
    """Smallest sampled plate angle with no sampled plate point inside the ellipsoid."""
    s = np.linspace(0, G.beam_length_m, n_s)
    y0, y1 = G.beam_y_range(beam)
    S, T = np.meshgrid(s, np.linspace(y0, y1, n_t))
    sa, ca, sb, cb = math.sin(roll), math.cos(roll), math.sin(pitch), math.cos(pitch)
    R = np.array([[cb, sb * sa, sb * ca], [0, ca, -sa], [-sb, cb * sa, cb * ca]])
    for th in np.linspace(0, math.pi / 2, n_theta):
        P = np.stack([S * math.sin(th) - x, T, hb + S * math.cos(th) - G.height_m])
        b = np.einsum("ji,j...->i...", R, P)
        if not ((b[0] / G.a_m) ** 2 + (b[1] / G.b_m) ** 2 + (b[2] / G.c_m) ** 2 < 1).any():
            return th
    return math.pi / 2


def test_contact_geometry_matches_brute_force():
    rng = np.random.default_rng(7)
    contacts = 0
    for _ in range(10):
        x, roll, pitch = rng.uniform(-0.11, 0.1), rng.uniform(-1.2, 1.2), rng.uniform(-0.8, 1.0)
        hb, beam = rng.uniform(0, 0.005), int(rng.integers(2))
        exact = deflection_angle(x, roll, pitch, hb, beam)
        vec = float(deflection_angles(x, roll, pitch, hb, beam))
        brute = brute_theta(x, roll, pitch, hb, beam)
        assert vec == pytest.approx(exact, abs=1e-8)
        # the brute force's angle step is 1e-3 rad and its sampling can only miss contact
        assert exact - 2e-3 <= brute <= exact + 1.1e-3, (x, roll, pitch, hb, beam)
        contacts += exact > 0
    assert contacts >= 4


def test_level_body_far_from_beams_has_no_contact_and_beams_mirror():
    assert deflection_angle(-0.2, 0, 0, 0, 0) == 0.0
    th1 = deflection_angle(-0.05, 0.3, -0.1, 0.001, 0)
    th2 = deflection_angle(-0.05, -0.3, -0.1, 0.001, 1)
    assert th1 > 0 and th1 == pytest.approx(th2, abs=1e-9)


def test_contact_force_is_linear_in_k_and_obeys_torque_balance():
    poses = np.array([[-0.08, 0.05, -0.1], [-0.05, -0.1, -0.2]])
    th, lever, n = unit_contact_forces(poses[:, 0], poses[:, 1], poses[:, 2], 0.0, 0)
    for k in (0.01, 0.25):
        for i, (x, r, p) in enumerate(poses):
            ext = external_forces(G, [BeamParams(k), BeamParams(0.0)], x, r, p)
            f = np.array(ext.contact_n)
            assert np.linalg.norm(f) == pytest.approx(k * th[i] / lever[i], rel=1e-6)
            assert f / np.linalg.norm(f) == pytest.approx(n[:, i], abs=1e-6)


def test_k0_is_the_papers():
    assert G.k0_nm_per_rad() == pytest.approx(0.028, abs=0.001)


def _no_control(k, fx, t_max_us=5_000_000):
    w = BeamsWorld([BeamParams(k), BeamParams(k)])
    while w.t_us < t_max_us and not (w.flipped or w.passed()):
        w.command(fx, 0, 0)
        w.step()
    return w


def test_no_control_outcomes_stiff_stuck_at_0p1_flips_at_1_and_flimsy_passes_at_1():
    stiff_weak = _no_control(0.25, 0.1, 2_000_000)
    assert not stiff_weak.flipped and not stiff_weak.passed() and stiff_weak.state.x_m < -0.09
    assert _no_control(0.25, 1.0).flipped
    flimsy = _no_control(0.01, 1.0)
    assert flimsy.passed() and not flimsy.flipped


def test_no_control_run_conserves_energy_and_flimsy_beams_yield_to_0p1_n():
    """Without damping or torques, T + E (Eq. 8) - F_x x is constant after contact: the contact
    and gravity forces are exactly the landscape's gradient. The 0.1 N push into flimsy beams
    (paper: stuck) stalls pitched up, then creeps over, with no energy gained."""
    g, k, fx = G, 0.01, 0.1
    w = BeamsWorld([BeamParams(k), BeamParams(k)])
    total, slowest = [], 1.0
    while w.t_us < 5_000_000 and not (w.flipped or w.passed()):
        w.command(fx, 0, 0)
        w.step()
        if w.first_contact_us is not None:
            s, th = w.state, w.last.theta_rad
            kinetic = 0.5 * (g.mass_kg * s.vx_m_s ** 2 + g.inertia_kg_m2[0] * s.roll_rate_rad_s ** 2
                             + g.inertia_kg_m2[1] * s.pitch_rate_rad_s ** 2)
            total.append(kinetic + float(gravity_energy_j(s.roll_rad, s.pitch_rad))
                         + 0.5 * k * (th[0] ** 2 + th[1] ** 2) - fx * s.x_m)
            slowest = min(slowest, s.vx_m_s)
    assert np.ptp(total) < 5e-6                     # joules, over the whole run
    assert w.passed() and slowest < 0.04


def test_a_plate_under_the_body_stays_there_once_its_upright_position_clears():
    """Pitched up 10 deg with the tail just past the hinge line, the upright plate misses the body
    (the landscape's smallest angle is 0), but a plate lying under it at 73 deg cannot swing
    back through the body: it stays in contact."""
    x, pitch = 0.1026, math.radians(-9.92)
    assert deflection_angle(x, 0.0, pitch, 0.0, 0) == 0.0
    beams = [BeamParams(0.01), BeamParams(0.01)]
    under = external_forces(G, beams, x, 0.0, pitch, [math.radians(73.6)] * 2)
    assert math.degrees(under.theta_rad[0]) == pytest.approx(73.6, abs=0.5) and under.contact_n[2] > 0
    assert external_forces(G, beams, x, 0.0, pitch).theta_rad == (0.0, 0.0)     # upright stays upright
    # a plate lying flatter, clear of the body, springs up until it meets the underside
    flatter = external_forces(G, beams, x, 0.0, pitch, [math.radians(85)] * 2)
    assert flatter.theta_rad == pytest.approx(under.theta_rad, abs=1e-9)


def test_saturation_and_determinism():
    w = BeamsWorld([BeamParams(0.25), BeamParams(0.25)], noise=0.2, seed=3)
    assert w.command(5, -1, 1) == (2.0, -0.1, 0.1)
    runs = []
    for _ in range(2):
        w = BeamsWorld([BeamParams(0.25), BeamParams(0.27)], noise=0.2, seed=3)
        out = []
        for _ in range(2000):
            w.command(1.0, 0, 0)
            w.step()
            if w.t_us % SENSOR_PERIOD_US == 0:
                out.append(w.sense_force())
        runs.append(out)
    assert runs[0] == runs[1] and any(f != (0.0, 0.0, 0.0) for f in runs[0])
