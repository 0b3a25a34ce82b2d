"""The 3D scene in a recorded run: every ``foxglove.*`` message decodes with the stock
decoders, the geometry has the world's sizes, plates change colour, feet carry the weight,
and the scene's topics are added beside the old ones without touching them."""
from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from hexhil.hil import scenario as scenario_mod
from hexhil.hil.run.rig import make_world
from hexhil.hil.world import scene as scene_mod
from hexhil.hil.world.beam_body import PAPER_BODY
from hexhil.hil.world.beams import BeamsWorld, BodyState
from hexhil.trace import topics
from conftest import ROOT, hexhil_in_process as hexhil


def _run(tmp_path: Path, name: str, *extra: str) -> Path:
    out = tmp_path / f"{name}.mcap"
    r = hexhil("run", f"scenarios/{name}.toml", "--out", str(out), *extra)
    assert r.returncode == 0, r.stderr
    return out


def _decoded(path: Path) -> dict[str, list]:
    """topic -> decoded messages of every foxglove.* channel, via mcap-protobuf's decoder."""
    out: dict[str, list] = {}
    factory, decoders = DecoderFactory(), {}
    with open(path, "rb") as f:
        for schema, channel, msg in make_reader(f).iter_messages(log_time_order=True):
            if schema.name.startswith("foxglove."):
                if channel.id not in decoders:
                    decoders[channel.id] = factory.decoder_for(channel.message_encoding, schema)
                out.setdefault(channel.topic, []).append(decoders[channel.id](msg.data))
    return out


@pytest.fixture(scope="module")
def hexapod_trace(tmp_path_factory):
    return _decoded(_run(tmp_path_factory.mktemp("scene"), "obstacles-high-large",
                         "--duration", "3"))


def test_scene_decodes_and_has_the_worlds_sizes(hexapod_trace):
    msgs = hexapod_trace
    assert {topics.T_BODY, topics.T_JOINTS, topics.T_SCENE, topics.T_SCENE_FRAMES,
            topics.T_SCENE_FORCES} <= set(msgs)
    # 10 Hz: the first wake, then every 100 ms on the grid up to the end (3.0 s)
    assert len(msgs[topics.T_SCENE_FRAMES]) == len(msgs[topics.T_BODY]) == 31
    sc = scenario_mod.load_scenario(ROOT / "scenarios/obstacles-high-large.toml")
    world = make_world(sc, sc.scenario.seed)
    m = world.model
    entities = {e.id: e for e in msgs[topics.T_SCENE][0].entities}
    for name, (kind, size) in {"body": ("cubes", [2 * v for v in world.params.body_half_m]),
                               "LF_foot": ("spheres", [2 * world.params.foot_radius_m] * 3)
                               }.items():
        prim = getattr(entities[name], kind)[0]
        assert [prim.size.x, prim.size.y, prim.size.z] == pytest.approx(size)
    gid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "RH_tibia")
    tibia = entities["RH_tibia"]
    assert tibia.frame_id == "RH_tibia" and tibia.frame_locked
    r, half = m.geom_size[gid][:2]
    assert tibia.cylinders[0].size.z == pytest.approx(2 * (half + r))
    assert 2 * half == pytest.approx(world.params.tibia_m)
    assert sum(e.id.startswith("obstacle") for e in entities.values()) == len(world.obstacles)
    frames = msgs[topics.T_SCENE_FRAMES][-1].transforms
    assert {t.child_frame_id for t in frames} >= {e.frame_id for e in entities.values()} - {"world"}


def test_plates_turn_red_and_feet_carry_the_weight(hexapod_trace):
    msgs = hexapod_trace
    updates = msgs[topics.T_SCENE]
    assert len(updates) >= 2  # the geometry again when a switch plate was pressed
    reds = [e.id for u in updates[1:] for e in u.entities
            if e.cubes and e.cubes[0].color.r > 0.9 and e.id.endswith("_plate")]
    assert reds
    for update in msgs[topics.T_SCENE_FORCES][5:]:  # walking: three to six feet down
        forces = update.entities[0]
        assert forces.frame_id == "world" and 3 <= len(forces.arrows) <= 6
        # the arrows' vertical parts carry the 1.5 kg robot (0.02 m a newton), give or take
        # the swing legs' impacts and the body's accelerations
        up_m = 0.0
        for a in forces.arrows:  # the arrow's +x turned by its quaternion, z component
            q = a.pose.orientation
            up_m += (a.shaft_length + a.head_length) * 2 * (q.x * q.z - q.w * q.y)
        assert up_m / 0.02 == pytest.approx(1.5 * 9.81, rel=0.5)


def test_beams_scene(tmp_path):
    msgs = _decoded(_run(tmp_path, "beams-stiff"))
    entities = {e.id: e for e in msgs[topics.T_SCENE][0].entities}
    body = entities["body"].spheres[0].size
    assert [body.x, body.y, body.z] == pytest.approx([0.24, 0.14, 0.06])  # seed 000 Sec. II-A
    assert entities["beam0"].cubes[0].size.z == pytest.approx(0.16)
    frames = {t.child_frame_id for t in msgs[topics.T_SCENE_FRAMES][-1].transforms}
    assert frames == {"body", "beam0", "beam1"}
    assert any(e.arrows for u in msgs[topics.T_SCENE_FORCES] for e in u.entities)


def test_quaternion_of_beams_body_is_ry_rx():
    """The body frame's rotation is R = Ry(pitch) Rx(roll), as seed 000 defines it."""
    state = BodyState(roll_rad=0.3, pitch_rad=-0.2)
    world = BeamsWorld([], PAPER_BODY, state)
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, np.array(scene_mod.beams_frames(world)[0].quat_wxyz))
    c, s = np.cos(-0.2), np.sin(-0.2)
    ry = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    c, s = np.cos(0.3), np.sin(0.3)
    rx = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    np.testing.assert_allclose(mat.reshape(3, 3), ry @ rx, atol=1e-6)  # float32 scene


def test_relative_frames_compose_to_mujocos_world_poses():
    sc = scenario_mod.load_scenario(ROOT / "scenarios/obstacles-high-large.toml")
    world = make_world(sc, 0)
    world.drives.goal_rad += np.linspace(-0.4, 0.4, 18)  # bend every joint a little
    world.advance_to(200_000)
    mujoco.mj_kinematics(world.model, world.data)  # xpos/xquat of the qpos after the step
    pose = {"world": (np.zeros(3), np.array([1.0, 0, 0, 0]))}
    for f in world.scene_frames():
        p, q = pose[f.parent]
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, q)
        quat = np.zeros(4)
        mujoco.mju_mulQuat(quat, q, np.array(f.quat_wxyz))
        pose[f.id] = (p + rot.reshape(3, 3) @ np.array(f.position_m), quat)
    for b in range(1, world.model.nbody):
        name = mujoco.mj_id2name(world.model, mujoco.mjtObj.mjOBJ_BODY, b)
        # float32 values (hil/world/scene.py rounds the scene for size)
        np.testing.assert_allclose(pose[name][0], world.data.xpos[b], atol=1e-6)
        np.testing.assert_allclose(pose[name][1], world.data.xquat[b], atol=1e-6)


def test_a_samples_frames_and_forces_are_what_the_world_was_when_taken():
    """The hexapod hands the recorder its frames and forces as raw values (joint
    coordinates, MuJoCo's contacts), made into poses and sums only where they are encoded,
    later or in another process: they must be the sample's, not the world's of then."""
    import pickle

    sc = scenario_mod.load_scenario(ROOT / "scenarios/obstacles-high-large.toml")
    world = make_world(sc, 0)
    world.drives.goal_rad += np.linspace(-0.4, 0.4, 18)
    world.advance_to(300_000)
    frames, forces = world.scene_frames(), world.scene_arrows()
    read_now = list(world.scene_frames()), list(world.scene_arrows())
    assert any(a.force_n != (0.0, 0.0, 0.0) for a in read_now[1])   # feet on the ground
    world.advance_to(400_000)
    later = list(world.scene_frames()), list(world.scene_arrows())
    assert later != read_now
    for held, now in ((frames, read_now[0]), (forces, read_now[1])):
        assert list(pickle.loads(pickle.dumps(held))) == now   # the encoding child's copy
        assert list(held) == now and len(held) == len(now) and held[-1] == now[-1]


def test_frame_transforms_encoder_matches_the_generated_class():
    from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms

    from hexhil.trace import protobuf as pb

    frames = [("body", "world", (0.1, 0.0, 0.09), (0.99, 0.0, 0.1, -0.0)),
              ("LF_coxa", "body", (0.1, 0.06, 0.0), (0.92, 0.0, 0.0, 0.38))]
    msg = FrameTransforms()
    for child, parent, p, (w, x, y, z) in frames:
        t = msg.transforms.add(parent_frame_id=parent, child_frame_id=child)
        t.timestamp.FromNanoseconds(1_234_567_890)
        t.translation.x, t.translation.y, t.translation.z = p
        t.rotation.w, t.rotation.x, t.rotation.y, t.rotation.z = w, x, y, z
    assert pb.encode_frame_transforms(1_234_567_890, frames) == msg.SerializeToString()
