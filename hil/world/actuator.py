"""AX-12-like joint drives in MuJoCo, behind the servo ``Actuator`` seam (hil/servobus/drive.py).

The emulated servo owns its control table; it hands Goal Position, Moving Speed, Torque
Limit, Torque Enable and the compliance registers to ``command`` and reads Present
Position/Speed/Load back from ``state``, which come from the physics.

Drive model (one vectorised bank for all 18 joints, evaluated every physics step):

- the goal is approached through a set-point that moves at most at the Moving Speed limit;
- the servo's duty ``u`` follows the AX-12 compliance curve on the set-point error ``e``:
  0 inside the compliance margin, then ``punch + (|e| - margin) / slope`` (margin and slope
  in position units, the slope being the error over which duty rises to 100 %), saturated
  at the Torque Limit fraction;
- the gearmotor gives ``tau = tau_stall * u - (tau_stall / omega_noload) * qdot``: the
  speed-dependent torque drop of a DC motor. The back-EMF term is the joint's MuJoCo
  damping (integrated implicitly, so 2 ms steps stay stable); ``tau_stall * u`` is the
  actuator control. With Torque Enable off the duty is 0 and the joint is back-driven
  against the gear train's damping only.

Constants (``Motor``): the model's e-manual specifications, held by its control table
(protocol/dynamixel/ax12.py, xl430.py, xm430.py: stall torque, no-load speed, rated
supply). The scenario's ``bus.model`` picks one for all 18 joints.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from hexhil.hil.world import drive_core
from hexhil.hil.world.drive_layout import (  # noqa: F401 (the drives' units, here too)
    POSITION_UNIT_RAD, PUNCH_FRACTION_PER_UNIT)
from hexhil.protocol.dynamixel import ax12, models

ROTOR_ARMATURE_KG_M2 = 0.0015   # reflected rotor inertia through the 254:1 gear train


@dataclass(frozen=True)
class Motor:
    """A servo's gearmotor at its rated supply (e-manual specifications)."""

    name: str
    stall_torque_nm: float
    no_load_speed_rad_s: float
    rated_supply_v: float

    @property
    def back_emf_damping_nm_s(self) -> float:
        return self.stall_torque_nm / self.no_load_speed_rad_s


def motor(model: str) -> Motor:
    """A servo model's gearmotor, from its control table's specifications
    (protocol/dynamixel/models.py)."""
    t = models.table(model)
    return Motor(model, t.STALL_TORQUE_NM, t.NO_LOAD_RPM * 2.0 * math.pi / 60.0,
                 t.RATED_SUPPLY_V)


AX12 = motor(ax12.MODEL_NAME)


# (cw margin, ccw margin, cw slope, ccw slope, punch) in AX-12 raw units: e-manual defaults.
DEFAULT_COMPLIANCE = (1, 1, 32, 32, 32)


class DriveBank:
    """The state of all joints' servo drives, as numpy arrays (SI units), and their
    arithmetic compiled (hil/world/drive_core.c): one bank for the servos served in Python
    (``MujocoActuator``) and the compiled servo bank (hil/servobus/servo_core.c) alike.

    ``joints``: the measured angles and speeds (views the world's physics updates in place)
    that a joint's state and a command's resume read; without, the joints rest at ``q0``.
    """

    def __init__(self, q0_rad: np.ndarray, motor: Motor = AX12,
                 joints: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        n = len(q0_rad)
        self.motor = motor
        self.goal_rad = np.array(q0_rad, dtype=float)
        self.setpoint_rad = np.array(q0_rad, dtype=float)
        self.speed_limit_rad_s = np.full(n, motor.no_load_speed_rad_s)
        self.torque_limit = np.ones(n)
        self.enabled = np.ones(n, dtype=bool)
        self.margin_rad = np.zeros((2, n))   # row 0: CW (e < 0), row 1: CCW (e > 0)
        self.slope_rad = np.zeros((2, n))
        self.punch = np.zeros(n)
        self.duty = np.zeros(n)
        self.read_offset_rad = np.zeros(n)   # potentiometer zero offsets (real model)
        # the compliance registers each joint's margin, slope and punch were last set from
        # (NaN: never)
        self.compliance_seen = np.full((n, 5), np.nan)
        q, qd = joints if joints is not None else (np.array(q0_rad, dtype=float), np.zeros(n))
        self.compiled = drive_core.CompiledDrives(
            {"goal": self.goal_rad, "setpoint": self.setpoint_rad,
             "speed": self.speed_limit_rad_s, "torque_limit": self.torque_limit,
             "margin": self.margin_rad, "slope": self.slope_rad, "punch": self.punch,
             "duty": self.duty, "compliance": self.compliance_seen, "enabled": self.enabled,
             "q": q, "qd": qd, "offset": self.read_offset_rad}, motor.no_load_speed_rad_s)
        for i in range(n):
            self.set_compliance(i, DEFAULT_COMPLIANCE)

    def set_compliance(self, i: int, compliance: tuple[int, int, int, int, int]) -> None:
        """Joint ``i``'s margins, slopes and punch from the compliance registers (raw)."""
        self.compiled.compliance(i, compliance)

    def control_into(self, q_rad: np.ndarray, dt_s: float, ctrl: np.ndarray) -> None:
        """Advance set-points by one step and write the motor torques (N m) into ``ctrl``
        (the world's MjData.ctrl): one compiled call a physics step."""
        self.compiled.duty(q_rad, dt_s, ctrl, self.motor.stall_torque_nm)

    def control(self, q_rad: np.ndarray, dt_s: float) -> np.ndarray:
        """Advance set-points by one step and return the motor torques (N m) to apply."""
        return self.motor.stall_torque_nm * self.duty_for(q_rad, dt_s)

    def duty_for(self, q_rad: np.ndarray, dt_s: float) -> np.ndarray:
        """Advance set-points by one step; the signed duty on the measured angles ``q_rad``
        (``self.duty``, updated in place). The set-point moves toward the goal by at most
        the speed limit's step; the duty is the error beyond the compliance margin over the
        slope, plus punch, capped at the torque limit, signed as the error, zero inside the
        margin or with torque off."""
        self.compiled.duty(q_rad, dt_s)
        return self.duty


class JointWorld(Protocol):
    """What a joint needs of its world (hil/world/hexapod_world.py's HexapodWorld): its drives,
    its buffers for the compiled servo bank and its clock. Declared here so this module
    never imports the world that imports it."""

    drives: DriveBank

    def joint_buffers(self) -> dict[str, Any]: ...

    def advance_to(self, t_us: int) -> None: ...


class MujocoActuator:
    """One joint of the world, driven like its servo (implements the servo Actuator seam)."""

    def __init__(self, world: JointWorld, index: int) -> None:
        self.world = world
        self.index = index
        self._drives = world.drives.compiled

    def command(self, goal_rad: float, speed_limit_rad_s: float, torque_limit_frac: float,
                enabled: bool, compliance: tuple[int, int, int, int, int] | None = None) -> None:
        self._drives.command(self.index, goal_rad, speed_limit_rad_s, torque_limit_frac,
                             enabled, compliance)

    def joint_buffers(self) -> tuple[dict[str, Any], int]:
        """The world's drive bank and clock for the compiled servo bank
        (hil/servobus/servo_core.py) and this joint's index in it."""
        return self.world.joint_buffers(), self.index

    def state(self) -> tuple[float, float, float]:
        """Present position (rad), speed (rad/s) and load (signed fraction of stall torque)."""
        return self._drives.state(self.index)

    def advance_to(self, t_us: int) -> None:
        """Physics runs on the world's clock; asking a joint to catch up advances the world."""
        self.world.advance_to(t_us)
