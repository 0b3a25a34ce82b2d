"""Tibia limit switches: hysteresis, and a plate pressed by a real obstacle in MuJoCo."""
import mujoco
import numpy as np
import pytest

from hexhil.hil.scenario import parse
from hexhil.hil.world import actuator as act
from hexhil.hil.world.hexapod_world import LEGS, HexapodWorld, RobotParams
from hexhil.hil.world.switches import SwitchBank
from hexhil.protocol import hexapod as kin


def test_hysteresis_between_operating_and_release_force():
    sw = SwitchBank(2, on_n=1.0, off_n=0.4)
    assert not sw.update(np.array([0.9, 0.0]))
    assert sw.update(np.array([1.1, 0.0])) and sw.levels() == [True, False]
    assert not sw.update(np.array([0.5, 0.0]))        # between the thresholds: stays closed
    assert sw.update(np.array([0.3, 0.0])) and sw.levels() == [False, False]
    assert list(sw.presses) == [1, 0]
    with pytest.raises(ValueError):
        SwitchBank(6, on_n=0.2, off_n=0.5)


def test_model_matches_the_paper_robot():
    world = HexapodWorld(parse({"world": {}}), seed=0)
    m = world.model
    assert m.nu == 18 and m.njnt == 19                       # 18 servos + the free body
    assert float(np.sum(m.body_mass)) == pytest.approx(1.5, abs=1e-9)
    assert RobotParams().total_kg == pytest.approx(1.5)     # Sec. 3.1
    # link lengths of Fig. 12, read back from the compiled model
    femur = m.body("LF_femur").pos
    tibia = m.body("LF_tibia").pos
    assert (femur[0], tibia[0]) == pytest.approx((0.05, 0.082))
    assert m.geom("LF_foot").pos[2] == pytest.approx(-0.12)
    # neutral stance: body bottom 8 cm above the ground, every foot loaded
    world.advance_to(300_000)
    bottom = world.body_pose().z_m - world.params.body_half_m[2]
    assert bottom == pytest.approx(kin.BODY_CLEARANCE_M, abs=0.006)
    assert world.foot_contacts() == [True] * 6


def test_plate_faces_forward_and_an_obstacle_closes_only_that_legs_switch():
    # an obstacle just in front of the right-front foot; swing that leg forward into it
    nx, ny, _ = kin.neutral_foot(3)
    sc = {"world": {"terrain": "obstacles", "obstacles": [
        {"x_m": nx + 0.045, "y_m": ny, "length_m": 0.03, "width_m": 0.06, "height_m": 0.05}]}}
    world = HexapodWorld(parse(sc), seed=0)
    world.advance_to(200_000)
    leg = kin.Leg(3)
    acts = world.actuators()
    base = kin.neutral_foot(3)
    for k in range(1, 41):  # lift 3 cm and push the foot 6 cm forward over 0.8 s
        f = k / 40
        q = leg.ik(base[0] + 0.06 * f, base[1], base[2] + 0.03)
        for j in range(3):
            acts[9 + j].command(leg.servo_rad(j, q[j]), 0.0, 1.0, True, act.DEFAULT_COMPLIANCE)
        world.advance_to(200_000 + k * 20_000)
    assert world.switch_levels() == [False, False, False, True, False, False]
    assert world.plate_forces_n()[3] > world.switches.on_n
    first = [e for e in world.events if e.closed]
    assert first[0].leg == LEGS.index("RF")
    # the plate, not the foot, met the obstacle: a contact between plate geom and obstacle
    plate = mujoco.mj_name2id(world.model, mujoco.mjtObj.mjOBJ_GEOM, "RF_plate")
    pairs = {tuple(sorted(c)) for c in world.data.contact.geom[: world.data.ncon]}
    obstacle = mujoco.mj_name2id(world.model, mujoco.mjtObj.mjOBJ_GEOM, "obstacle0")
    assert tuple(sorted((plate, obstacle))) in pairs
