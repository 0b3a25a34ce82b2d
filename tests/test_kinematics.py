"""Leg IK/FK (protocol/hexapod.py) over the walking workspace, in CPython and MicroPython."""
import math
import os
import subprocess
import sys

import pytest

from hexhil.firmware import trajectory as traj
from mpy import ROOT, run_micropython
from hexhil.protocol import hexapod as kin


def workspace(leg):
    """Foot targets the gaits ask for: Eq. 2-4 swings of the initial (l_i 5 cm, h_i 3 cm),
    obstacle (l_k 10 cm, h_k 7 cm) and h_max = 12 cm (Eq. 15) steps, 3 cm either side."""
    nx, ny, nz = kin.neutral_foot(leg)
    for l, h in ((0.05, 0.03), (0.10, 0.07), (0.05, 0.12)):
        for k in range(11):
            t = k / 10
            s = traj.stroke(t, l, 2, 0.0) - 0.025
            z = traj.lift(t, h, -1e-12)
            for dy in (-0.03, 0.0, 0.03):
                yield nx + s, ny + dy, nz + z


@pytest.mark.parametrize("leg", range(6))
def test_ik_fk_round_trip_over_workspace(leg):
    L = kin.Leg(leg)
    n = 0
    for p in workspace(leg):
        q = list(L.ik(*p))
        f = L.fk(*q)
        assert max(abs(a - b) for a, b in zip(f, p)) < 1e-9, (p, q, f)
        n += 1
    assert L.clamped == 0 and n == 99


def test_neutral_stance_geometry_matches_fig12():
    L = kin.Leg(0)
    nx, ny, nz = kin.neutral_foot(0)
    assert nz == pytest.approx(-(0.08 + 0.015 - 0.01))     # body bottom 8 cm above ground
    q1, q2, q3 = L.ik(nx, ny, nz)
    assert q1 == pytest.approx(0.0, abs=1e-12)               # coxa along the mounting yaw
    # femur end and tibia end at the paper's link lengths
    knee = (kin.COXA_M + kin.FEMUR_M * math.cos(q2), kin.FEMUR_M * math.sin(q2))
    foot_r = kin.NEUTRAL_REACH_M
    assert math.hypot(foot_r - knee[0], nz - knee[1]) == pytest.approx(kin.TIBIA_M)


def test_unreachable_target_is_clamped_and_counted_not_raised():
    L = kin.Leg(3)
    q = list(L.ik(2.0, -2.0, 0.0))          # metres away
    x, y, z = L.fk(*q)
    assert L.clamped == 1
    mx, my, _ = kin.MOUNTS[3]
    assert math.hypot(x - mx, y - my) <= kin.COXA_M + kin.FEMUR_M + kin.TIBIA_M + 1e-6
    L.ik(kin.MOUNTS[3][0], kin.MOUNTS[3][1], 0.0)   # at the coxa joint itself
    assert L.clamped == 2
    for j in range(3):
        assert kin.JOINT_MIN[j] <= L.q[j] <= kin.JOINT_MAX[j]


def test_servo_angle_calibration_round_trip():
    L = kin.Leg(4, offsets=(0.01, -0.02, 0.03))
    L.directions = (1, -1, 1)
    for j, q in enumerate((0.3, -0.4, -1.2)):
        assert L.joint_rad(j, L.servo_rad(j, q)) == pytest.approx(q)
        lo, hi = L.servo_limits_rad(j)
        assert lo < hi


def test_round_trip_under_micropython(tmp_path):
    script = tmp_path / "k.py"
    script.write_text(
        "from protocol import hexapod as kin\n"
        "worst = 0.0\n"
        "for leg in range(6):\n"
        "    L = kin.Leg(leg)\n"
        "    nx, ny, nz = kin.neutral_foot(leg)\n"
        "    for dx in (-0.05, 0.0, 0.075):\n"
        "        for dz in (0.0, 0.07):\n"
        "            q = list(L.ik(nx + dx, ny, nz + dz))\n"
        "            f = L.fk(q[0], q[1], q[2])\n"
        "            e = max(abs(f[0] - nx - dx), abs(f[1] - ny), abs(f[2] - nz - dz))\n"
        "            worst = e if e > worst else worst\n"
        "print(worst < 1e-9, sum(kin.Leg(i).clamped for i in range(6)))\n")
    r = run_micropython(script)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["True", "0"]


GOALS_AGREE = """
from firmware.servo_goals import ServoGoals
from protocol import hexapod as kin
from protocol.dynamixel import ax12
goals = ServoGoals(20000)
goals.legs[4].directions = (1, -1, 1)          # a mirrored horn and calibration offsets
goals.legs[4].offsets = (0.01, -0.02, 0.03)
prev = [0.0] * 18
bad = n = 0
for leg in range(6):
    nx, ny, nz = kin.neutral_foot(leg)
    for dx in (-0.06, -0.013, 0.0, 0.021, 0.075, 0.4):
        for dz in (0.0, 0.031, 0.07, -0.2):
            for speed in (0.0, 1.0, 0.37):
                goals.set_leg(leg, nx + dx, ny + dx / 3, nz + dz, speed)
                L = goals.legs[leg]
                for j in range(3):
                    k = 3 * leg + j
                    rad = L.servo_rad(j, L.q[j])
                    lo, hi = goals.limits[k]
                    pos = min(hi, max(lo, ax12.rad_to_position(rad)))
                    spd = speed if speed > 0 else 1.5 * abs(rad - prev[k]) / 0.02
                    want = (rad, pos, ax12.rad_s_to_speed(spd))
                    bad += want != (goals.goal_rad[k], goals.positions[k], goals.speeds[k])
                    prev[k] = rad
                    n += 1
print(n, bad)
"""


def test_servo_goals_are_the_protocol_conversions(tmp_path):
    """ServoGoals.set_leg writes Leg.servo_rad, ax12.rad_to_position and rad_s_to_speed out
    for speed: its goals are those functions' bit for bit, clamped targets and a mirrored,
    offset leg included, under CPython and MicroPython."""
    script = tmp_path / "goals.py"
    script.write_text(GOALS_AGREE)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    for r in (subprocess.run([sys.executable, str(script)], env=env, capture_output=True,
                             text=True, timeout=120), run_micropython(script)):
        assert r.returncode == 0, r.stderr
        assert r.stdout.split() == ["1296", "0"]
