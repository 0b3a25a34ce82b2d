"""The hexapod of seed 003 in MuJoCo: MJCF generated from the robot's parameters, stepped in
lockstep virtual time, with ground truth (body pose, foot contacts, switch levels).

Robot (seed 003, Sec. 3.1 and Fig. 12): 1.5 kg, about 30 x 30 cm, coxa 5 cm, femur 8.2 cm,
tibia 12 cm, body bottom 8 cm above the ground in the neutral stance, 18 AX-12 joints.

Geometry comes from the robot description ``protocol/hexapod.py``, which the firmware
reads too (one source of truth for mounts, link lengths, body box, neutral stance and
servo directions). World x is the walking direction, z up; the robot starts at the origin
facing along x. Legs in servo-ID order LF, LM, LH, RF, RM, RH, each coxa, femur, tibia
(IDs 1-3 for LF ... 16-18 for RH).

Every MuJoCo joint angle IS the servo angle (0 at the AX-12 centre, position 512): coxa
along the leg's mounting yaw, femur horizontal, tibia perpendicular to the femur pointing
down. Positive femur lifts the knee and positive tibia swings the foot out; a servo mounted
mirrored (-1 in ``DIRECTIONS``) turns its joint axis the other way, as on the robot.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from hexhil.hil.scenario import Scenario, WorldKind
from hexhil.hil.world import actuator as act
from hexhil.hil.world import fidelity
from hexhil.hil.world import scene as scene_mod
from hexhil.hil.world import terrain as terrain_mod
from hexhil.hil.world.switches import SwitchBank
from hexhil.protocol import hexapod as robot_desc
from hexhil.protocol.errors import BadValue
from hexhil.protocol.hexapod import JOINTS, LEGS

PHYSICS_DT_US = 2000   # 2 ms steps: contact-stable with implicit joint damping (see docs)
JOINT_NAMES = tuple(f"{leg}_{part}" for leg in LEGS for part in JOINTS)   # servo-ID order


@dataclass(frozen=True)
class RobotParams:
    """Geometry and masses; lengths in metres, masses in kilograms."""

    coxa_m: float = robot_desc.COXA_M      # Fig. 12
    femur_m: float = robot_desc.FEMUR_M    # Fig. 12
    tibia_m: float = robot_desc.TIBIA_M    # Fig. 12, knee to the foot sphere's centre
    body_clearance_m: float = robot_desc.BODY_CLEARANCE_M  # ground to body bottom (Fig. 12)
    # body box half-extents; the coxa joints lie on its mid-plane
    body_half_m: tuple[float, float, float] = robot_desc.BODY_HALF_M
    mounts: tuple[tuple[float, float, float], ...] = robot_desc.MOUNTS  # (x, y, yaw) body frame
    foot_radius_m: float = robot_desc.FOOT_RADIUS_M
    tibia_radius_m: float = 0.008
    # 1.5 kg in all (Sec. 3.1): body with electronics and coxa servos, links carry servos
    body_kg: float = 0.66
    coxa_kg: float = 0.06
    femur_kg: float = 0.07
    tibia_kg: float = 0.01          # with the 1 g foot and the 1 g switch plate
    foot_friction: float = 1.0
    obstacle_friction: float = 0.5
    plate_half_m: tuple[float, float, float] = (0.002, 0.015, 0.04)  # switch plate
    plate_gap_m: float = 0.004      # plate stands this far in front of the tibia surface
    plate_low_m: float = 0.002      # plate bottom edge above the foot centre (1.2 cm off the ground)

    @property
    def body_height_m(self) -> float:
        """Body centre (and coxa joint plane) height in the neutral stance."""
        return self.body_clearance_m + self.body_half_m[2]

    @property
    def total_kg(self) -> float:
        return self.body_kg + 6 * (self.coxa_kg + self.femur_kg + self.tibia_kg)


def neutral_joints() -> np.ndarray:
    """The 18 servo angles of the neutral stance (feet on the ground)."""
    out = []
    for i in range(len(LEGS)):
        leg = robot_desc.Leg(i)
        q = list(leg.ik(*robot_desc.neutral_foot(i)))
        out += [leg.servo_rad(j, q[j]) for j in range(3)]
    return np.array(out)


_f = terrain_mod.mjcf_numbers


def mjcf(params: RobotParams, obstacles: list[terrain_mod.Obstacle], ground_friction: float,
         real: fidelity.RealModel | None = None, motor: act.Motor = act.AX12) -> str:
    """The MJCF document for the robot on flat ground with the given obstacles.

    Collision filtering: robot geoms have contype 1 / conaffinity 0, the ground and fixed
    obstacles contype 0 / conaffinity 1, so the robot touches the world but not itself.
    The real model (hil/world/fidelity.py) rounds the switch plate's face, gives the leg's
    polypropylene friction priority over the obstacles' and may make obstacles loose.
    """
    p = params
    bx, by, bz = p.body_half_m
    robot = 'contype="1" conaffinity="0"'
    plate_type, leg_extra = "box", ""
    if real is not None:
        plate_type, leg_extra = "ellipsoid", ' priority="2"'
    legs = []
    for name, (mx, my, yaw), dirs in zip(LEGS, p.mounts, robot_desc.DIRECTIONS):
        # switch plate faces the robot's forward direction (body +x) seen from this leg
        n_x, n_y = math.cos(yaw), -math.sin(yaw)
        off = p.tibia_radius_m + p.plate_gap_m + p.plate_half_m[0]
        pz = -(p.tibia_m - p.plate_low_m - p.plate_half_m[2])
        foot_z = -p.tibia_m
        plate_rot = _f(0, 0, -math.degrees(yaw))
        legs.append(f"""
    <body name="{name}_coxa" pos="{_f(mx, my, 0)}" euler="{_f(0, 0, math.degrees(yaw))}">
      <joint name="{name}_coxa" axis="0 0 1" range="-150 150"/>
      <geom type="capsule" fromto="0 0 0 {p.coxa_m} 0 0" size="0.012" mass="{p.coxa_kg}" {robot}/>
      <body name="{name}_femur" pos="{p.coxa_m} 0 0">
        <joint name="{name}_femur" axis="0 {-dirs[1]} 0" range="-150 150"/>
        <geom type="capsule" fromto="0 0 0 {p.femur_m} 0 0" size="0.012" mass="{p.femur_kg}" {robot}/>
        <body name="{name}_tibia" pos="{p.femur_m} 0 0">
          <joint name="{name}_tibia" axis="0 {-dirs[2]} 0" range="-150 150"/>
          <geom name="{name}_tibia" type="capsule" fromto="0 0 0 0 0 {foot_z}"
                size="{p.tibia_radius_m}" mass="{p.tibia_kg - 0.002}" friction="0.3"{leg_extra} {robot}/>
          <geom name="{name}_foot" type="sphere" pos="0 0 {foot_z}" size="{p.foot_radius_m}"
                mass="0.001" friction="{p.foot_friction}" {robot}/>
          <geom name="{name}_plate" type="{plate_type}" pos="{_f(n_x * off, n_y * off, pz)}"
                euler="{plate_rot}" size="{_f(*p.plate_half_m)}" mass="0.001" friction="0.3"{leg_extra} {robot}/>
          <site name="{name}_plate" type="box" pos="{_f(n_x * (off + 0.002), n_y * (off + 0.002), pz)}"
                euler="{plate_rot}" size="{_f(p.plate_half_m[0] + 0.004, p.plate_half_m[1] + 0.003, p.plate_half_m[2] + 0.003)}"/>
          <site name="{name}_foot" type="sphere" pos="0 0 {foot_z}" size="{p.foot_radius_m + 0.004}"/>
        </body>
      </body>
    </body>""")
    assets, obs, loose = "", terrain_mod.mjcf_fixed(obstacles, p.obstacle_friction), ""
    sleep = "/>"
    if real is not None and real.free_obstacles:
        obs = ""
        assets, loose = terrain_mod.mjcf_free(obstacles, fidelity.OBSTACLE_FLOOR_FRICTION,
                                              fidelity.obstacle_mass_kg)
        assets = f"\n  <asset>{assets}\n  </asset>"
    # resting loose obstacles sleep (MuJoCo islands) until the robot touches them
        sleep = '>\n    <flag sleep="enable"/>\n  </option>'
    stall = motor.stall_torque_nm if real is None else float(real.stall_nm.max())
    motors = "".join(
        f'\n    <motor name="{leg}_{j}" joint="{leg}_{j}" ctrlrange="{_f(-stall, stall)}"/>'
        for leg in LEGS for j in JOINTS)
    sensors = "".join(f'\n    <touch name="{leg}_plate" site="{leg}_plate"/>' for leg in LEGS) + \
        "".join(f'\n    <touch name="{leg}_foot" site="{leg}_foot"/>' for leg in LEGS)
    return f"""<mujoco model="hexhil-hexapod">
  <compiler angle="degree" autolimits="true"/>
  <option timestep="{PHYSICS_DT_US * 1e-6}" integrator="implicitfast" cone="elliptic"{sleep}
  <default>
    <joint damping="{motor.back_emf_damping_nm_s:.6g}" armature="{act.ROTOR_ARMATURE_KG_M2}"/>
    <motor ctrllimited="true"/>
  </default>{assets}
  <worldbody>
    <geom name="ground" type="plane" size="5 5 0.1" friction="{ground_friction}" contype="0" conaffinity="1"/>{obs}
    <body name="body" pos="0 0 {p.body_height_m:.6g}">
      <freejoint name="root"/>
      <geom name="body" type="box" size="{_f(bx, by, bz)}" mass="{p.body_kg}" {robot}/>{"".join(legs)}
    </body>{loose}
  </worldbody>
  <actuator>{motors}
  </actuator>
  <sensor>{sensors}
  </sensor>
</mujoco>
"""


def yaw_rad(w: float, x: float, y: float, z: float) -> float:
    """Heading (Z-Y'-X' yaw) of a unit quaternion, as MuJoCo's qpos and /body hold it."""
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


@dataclass
class BodyPose:
    """Ground-truth body pose, world frame: position (m), yaw/pitch/roll (rad) for people and
    the run summary, and MuJoCo's own unit quaternion for the recorder (no round trip)."""

    x_m: float
    y_m: float
    z_m: float
    yaw_rad: float
    pitch_rad: float
    roll_rad: float
    quat_wxyz: tuple[float, float, float, float]


@dataclass
class SwitchEvent:
    t_us: int
    leg: int
    closed: bool
    body_x_m: float
    body_y_m: float
    yaw_rad: float


@dataclass
class HexapodWorld:
    """The robot and its terrain, advanced in integer virtual microseconds.

    ``scenario`` is a checked scenario (``hil.scenario.parse``); its ``[world]``
    section selects flat ground or obstacles, the ground friction and the fidelity.
    """

    scenario: Scenario
    seed: int = 0
    params: RobotParams = field(default_factory=RobotParams)

    def __post_init__(self) -> None:
        world = self.scenario.world
        if world.kind not in (None, WorldKind.HEXAPOD):
            raise BadValue(f"{self.scenario.path}: world.kind {world.kind.value!r} "
                           f"is not the hexapod world")
        self.obstacles = terrain_mod.from_scenario(world, self.seed)
        self.motor = act.motor(self.scenario.bus.model)
        self.real = fidelity.from_scenario(world, self.motor, self.seed,
                                           self.params.foot_friction, len(LEGS) * len(JOINTS),
                                           len(LEGS))
        self.xml = mjcf(self.params, self.obstacles, world.friction, self.real, self.motor)
        self.model = mujoco.MjModel.from_xml_string(self.xml)
        if self.real is not None:   # this trial's foot friction (slip noise)
            for leg, mu in zip(LEGS, self.real.foot_friction):
                self.model.geom(f"{leg}_foot").friction[0] = mu
        self.data = mujoco.MjData(self.model)
        q0 = neutral_joints()
        depth_m = self.params.body_height_m - self.params.foot_radius_m
        if abs(depth_m - robot_desc.STANCE_DEPTH_M) > 1e-9:
            raise ValueError("world parameters disagree with protocol/hexapod.py on the stance depth")
        # Views into MjData's fixed buffers: the free joint comes first (7 coordinates,
        # 6 velocities), then the legs in servo-ID order; touch sensors: plates, then feet.
        self._q = self.data.qpos[7:25]
        self._ctrl = self.data.ctrl      # the 18 joints' motor torques
        self._qd = self.data.qvel[6:24]
        self._plate_n = self.data.sensordata[0:6]
        self._foot_n = self.data.sensordata[6:12]
        self._q[:] = q0
        mujoco.mj_forward(self.model, self.data)
        joints = (self._q, self._qd)
        self.drives = (act.DriveBank(q0, self.motor, joints) if self.real is None
                       else fidelity.RealDriveBank(q0, self.real, joints))
        self.switches = SwitchBank(len(LEGS))
        self.t_us = 0
        self.dt_s = PHYSICS_DT_US * 1e-6
        self.events: list[SwitchEvent] = []
        self.trajectory: list[tuple[int, float, float, float]] = []  # (t_us, x, y, yaw) at 10 Hz
        self._actuators = [act.MujocoActuator(self, i) for i in range(18)]
        self._buffers: dict[str, Any] | None = None
        self._backup: Any = None   # checkpoint()'s copy of the MjData
        self._sample()

    # --- the simulator's hooks ----------------------------------------------------------
    def actuators(self) -> list[act.MujocoActuator]:
        """The 18 joints in servo-ID order (LF coxa, femur, tibia, LM ..., RH tibia)."""
        return self._actuators

    def advance_to(self, t_us: int) -> None:
        """Step the physics up to ``t_us`` (whole 2 ms steps; never past it)."""
        m, d = self.model, self.data
        while self.t_us + PHYSICS_DT_US <= t_us:
            self.drives.control_into(self._q, self.dt_s, self._ctrl)
            mujoco.mj_step(m, d)
            self.t_us += PHYSICS_DT_US
            if self.switches.update(self._plate_n):
                self._log_switches()
            if self.t_us % 100_000 == 0:
                self._sample()

    def checkpoint(self) -> tuple | None:
        """All that ``advance_to`` changes, for ``restore``: the run's lookahead
        (hil/run/lookahead.py) steps the world ahead of the run's clock and takes the steps
        back when the firmware's next batch does not lead there. None with the real
        robot's drives (hil/world/fidelity.py), whose state is more than these arrays."""
        if type(self.drives) is not act.DriveBank:
            return None
        if self._backup is None:
            self._backup = mujoco.MjData(self.model)
        mujoco.mj_copyData(self._backup, self.model, self.data)
        d = self.drives
        return (self.t_us, d.setpoint_rad.copy(), d.duty.copy(), self.switches.state(),
                len(self.events), len(self.trajectory))

    def restore(self, saved: tuple) -> None:
        """Back to a ``checkpoint``: the same bits as if the steps since had not been taken."""
        mujoco.mj_copyData(self.data, self.model, self._backup)
        self.t_us, setpoint, duty, switches, events, samples = saved
        self.drives.setpoint_rad[:] = setpoint
        self.drives.duty[:] = duty
        self.switches.set_state(switches)
        del self.events[events:]
        del self.trajectory[samples:]

    def next_step_us(self) -> int:
        """When the next physics step is due: ``advance_to`` an earlier time does nothing."""
        return self.t_us + PHYSICS_DT_US

    def joint_buffers(self) -> dict[str, Any]:
        """The compiled drive bank's address and this world's ``advance_to`` and
        ``next_step_us``: what the compiled servo bank and status reads use
        (hil/servobus/servo_core.py, status_reads.py)."""
        if self._buffers is None:
            self._buffers = {"drives": self.drives.compiled.ref, "advance": self.advance_to,
                             "next_step_us": self.next_step_us}
        return self._buffers

    def switch_levels(self) -> list[bool]:
        """Limit-switch levels, True = pressed, in leg order LF, LM, LH, RF, RM, RH."""
        return self.switches.levels()

    def body_pose(self) -> BodyPose:
        px, py, pz, w, x, y, z = self.data.qpos[:7].tolist()  # floats: numpy scalars are slow
        yaw = yaw_rad(w, x, y, z)
        pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
        roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
        return BodyPose(px, py, pz, yaw, pitch, roll, (w, x, y, z))

    def foot_contacts(self) -> list[bool]:
        """Ground truth: which feet carry load (touch force above 0.05 N)."""
        return [bool(f > 0.05) for f in self._foot_n]

    def plate_forces_n(self) -> list[float]:
        return [float(f) for f in self._plate_n]

    def joint_positions(self) -> np.ndarray:
        return self._q.copy()

    def joint_velocities(self) -> np.ndarray:
        return self._qd.copy()

    def joint_efforts_nm(self) -> np.ndarray:
        """Motor torque on each joint (N m), from the drive model."""
        return self.data.qfrc_actuator[6:24].copy()

    # --- the 3D scene (hil/world/scene.py) ----------------------------------------------
    @functools.cached_property
    def _scene(self) -> scene_mod.ModelScene:
        return scene_mod.ModelScene(self.model, [f"{leg}_plate" for leg in LEGS],
                                    [f"{leg}_foot" for leg in LEGS])

    def scene_shapes(self) -> list[scene_mod.Shape]:
        """The model's geoms; the switch plates red while pressed."""
        return self._scene.shapes(self.switches.levels())

    def scene_frames(self) -> scene_mod.JointFrames:
        """The links' poses, made where the recorder encodes them (``JointFrames``)."""
        return self._scene.frames(self.data)

    def scene_arrows(self) -> scene_mod.ContactForces:
        """Each foot's contact force (N), summed where the recorder encodes it."""
        return self._scene.arrows(self.data)

    @staticmethod
    def joint_names() -> list[str]:
        """MJCF joint names in servo-ID order, as they appear in JointStates."""
        return list(JOINT_NAMES)

    # --- logging ------------------------------------------------------------------------
    def _sample(self) -> None:
        pose = self.body_pose()
        self.trajectory.append((self.t_us, pose.x_m, pose.y_m, pose.yaw_rad))

    def _log_switches(self) -> None:
        pose = self.body_pose()
        logged = {e.leg: e.closed for e in self.events}
        for leg, closed in enumerate(self.switches.levels()):
            if logged.get(leg, False) != closed:
                self.events.append(SwitchEvent(self.t_us, leg, closed, pose.x_m, pose.y_m, pose.yaw_rad))
