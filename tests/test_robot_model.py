"""The URDF (``hexhil model urdf``) loads in a maintained parser and agrees with the MuJoCo
world it shares its description with: joint axes, joint origins, link lengths, and the
foot positions at random joint angles."""
from __future__ import annotations

import io
import subprocess
import sys

import mujoco
import numpy as np
import pytest
import yourdfpy

from hexhil.hil.world.hexapod_world import RobotParams, mjcf
from hexhil.robot_model import urdf
from hexhil.protocol.hexapod import JOINTS, LEGS


@pytest.fixture(scope="module")
def both():
    robot = yourdfpy.URDF.load(io.StringIO(urdf()), build_scene_graph=True,
                               load_meshes=False)
    model = mujoco.MjModel.from_xml_string(mjcf(RobotParams(), [], 1.0))
    return robot, model


def test_joints_match_the_world(both):
    robot, model = both
    names = [f"{leg}_{j}" for leg in LEGS for j in JOINTS]
    assert robot.actuated_joint_names == names
    for name in names:
        joint = robot.joint_map[name]
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        body = model.jnt_bodyid[jid]
        # the joint's axis in its parent's frame: URDF origin rotation x axis; MuJoCo's
        # body quaternion times its local axis
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, model.body_quat[body])
        np.testing.assert_allclose(joint.origin[:3, :3] @ joint.axis,
                                   rot.reshape(3, 3) @ model.jnt_axis[jid], atol=1e-9)
        np.testing.assert_allclose(joint.origin[:3, 3], model.body_pos[body], atol=1e-9)


def test_link_lengths_match_the_world(both):
    robot, model = both
    p = RobotParams()
    for leg in LEGS:
        assert robot.joint_map[f"{leg}_femur"].origin[0, 3] == pytest.approx(p.coxa_m)
        assert robot.joint_map[f"{leg}_tibia"].origin[0, 3] == pytest.approx(p.femur_m)
        assert robot.joint_map[f"{leg}_foot"].origin[2, 3] == pytest.approx(-p.tibia_m)
        gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"{leg}_tibia")
        assert 2 * model.geom_size[gid][1] == pytest.approx(p.tibia_m)


def test_feet_match_the_world_at_random_angles(both):
    robot, model = both
    data = mujoco.MjData(model)
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = rng.uniform(-1.0, 1.0, 18)
        robot.update_cfg(q)
        data.qpos[:7] = [0, 0, 0, 1, 0, 0, 0]
        data.qpos[7:25] = q
        mujoco.mj_kinematics(model, data)
        for leg in LEGS:
            site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"{leg}_foot")
            foot = robot.get_transform(f"{leg}_foot", "body")[:3, 3]
            np.testing.assert_allclose(foot, data.site_xpos[site], atol=1e-9)


def test_cli_prints_both_descriptions():
    out = subprocess.run([sys.executable, "-m", "hexhil.cli", "model", "urdf"],
                         capture_output=True, text=True, check=True).stdout
    assert out == urdf()
    out = subprocess.run([sys.executable, "-m", "hexhil.cli", "model", "mjcf"],
                         capture_output=True, text=True, check=True).stdout
    assert out == mjcf(RobotParams(), [], 1.0)
