"""Open-loop walking of the MuJoCo hexapod through the servo Actuator seam.

Joint targets come from the firmware's own (plain Python) gait and Eq. 2-4 trajectory and
the robot description's kinematics (protocol/hexapod.py), run in CPython with no tactile rule: this tunes and checks the physics alone.
"""
import math

import pytest

from hexhil.firmware import gait as gait_mod
from hexhil.firmware import trajectory as traj
from hexhil.hil.scenario import parse
from hexhil.hil.world.hexapod_world import HexapodWorld
from hexhil.protocol import hexapod as kin

CYCLE_US = 20_000  # the firmware's 50 Hz loop


def walk(world: HexapodWorld, gait: str, duration_s: float, step_height_m: float = 0.03,
         step_length_m: float = 0.05) -> float:
    """Drive the world open-loop; returns the commanded distance (m).

    A stance foot sweeps l in (T - 1) of the T normalised units, so the body's nominal
    speed is l T / ((T - 1) period): 2 l / period for tripod, 1.2 l / period for wave.
    """
    period_s = step_length_m / {"tripod": 0.036, "wave": 0.013}[gait]  # Sec. 3.3 speeds
    g = gait_mod.Gait(gait, period_s)
    legs = [kin.Leg(i) for i in range(6)]
    acts = world.actuators()
    for k in range(int(duration_s * 1e6) // CYCLE_US):
        t_us = k * CYCLE_US
        g.advance(t_us)
        for i, leg in enumerate(legs):
            dx, dy, dz = traj.foot(g.t, step_length_m, step_height_m, g.T, g.phases[i], 0.0)
            nx, ny, nz = kin.neutral_foot(i)
            q = leg.ik(nx + dx - step_length_m / 2, ny + dy, nz + dz)
            for j in range(3):
                acts[3 * i + j].command(leg.servo_rad(j, q[j]), 0.0, 1.0, True, (1, 1, 32, 32, 32))
        world.advance_to(t_us + CYCLE_US)
    return step_length_m * g.T / ((g.T - 1) * period_s) * duration_s


@pytest.mark.parametrize("gait", ["tripod", "wave"])
def test_walks_straight_on_flat_ground(gait):
    world = HexapodWorld(parse({"world": {}}), seed=0)
    commanded = walk(world, gait, 12.0)
    pose = world.body_pose()
    assert pose.x_m == pytest.approx(commanded, rel=0.15)        # the 15 % criterion
    assert abs(pose.y_m) < 0.1 * commanded
    assert abs(math.degrees(pose.yaw_rad)) < 5
    assert world.switch_levels() == [False] * 6 and world.events == []
    assert 0.06 < pose.z_m < 0.10                                 # body near 8 cm
    # present load comes from physics: the femurs carry the body
    loads = [a.state()[2] for a in world.actuators()]
    assert max(abs(loads[3 * i + 1]) for i in range(6)) > 0.05


def test_obstacles_catch_legs_fire_switches_and_cost_distance():
    flat = HexapodWorld(parse({"world": {}}), seed=0)
    commanded = walk(flat, "tripod", 10.0, step_height_m=0.02)
    rough = HexapodWorld(parse({"world": {"terrain": "obstacles", "obstacles": [
        {"x_m": 0.33, "y_m": 0.20, "length_m": 0.03, "width_m": 0.08, "height_m": 0.05}]}}), seed=0)
    walk(rough, "tripod", 10.0, step_height_m=0.02)
    hit = [e.leg for e in rough.events if e.closed]
    assert hit and set(hit) <= {0, 1, 2}                 # only left legs meet a left obstacle
    pose, ref = rough.body_pose(), flat.body_pose()
    assert pose.x_m < ref.x_m - 0.02                     # legs caught: distance lost
    assert pose.yaw_rad > ref.yaw_rad + math.radians(2)  # left side held back: turned left
    assert ref.x_m == pytest.approx(commanded, rel=0.15)


def test_runs_are_bit_identical():
    sc = {"world": {"terrain": "obstacles", "density": "high", "height_class": "small", "length_m": 0.8}}
    a, b = HexapodWorld(parse(sc), seed=3), HexapodWorld(parse(sc), seed=3)
    walk(a, "tripod", 3.0)
    walk(b, "tripod", 3.0)
    assert a.data.qpos.tobytes() == b.data.qpos.tobytes()
    assert a.trajectory == b.trajectory
