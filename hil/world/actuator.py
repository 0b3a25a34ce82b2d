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
from hexhil.protocol.dynamixel import ax12, models

ROTOR_ARMATURE_KG_M2 = 0.0015   # reflected rotor inertia through the 254:1 gear train
POSITION_UNIT_RAD = math.radians(ax12.POSITION_RANGE_DEG / ax12.POSITION_MAX)
PUNCH_FRACTION_PER_UNIT = 1.0 / 1023.0


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
    """The state of all joints' servo drives, as numpy arrays (SI units)."""

    def __init__(self, q0_rad: np.ndarray, motor: Motor = AX12) -> None:
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
        self.read_offset_rad = [0.0] * n    # potentiometer zero offsets (real model)
        # the compliance registers each joint's margin, slope and punch were last set from
        # (NaN: never), shared with the compiled servo bank (hil/servobus/servo_core.c)
        self.compliance_seen = np.full((n, 5), np.nan)
        for i in range(n):
            self.set_compliance(i, DEFAULT_COMPLIANCE)
        self._compiled = drive_core.CompiledDuty(
            {"goal": self.goal_rad, "setpoint": self.setpoint_rad,
             "speed": self.speed_limit_rad_s, "torque_limit": self.torque_limit,
             "margin": self.margin_rad, "slope": self.slope_rad, "punch": self.punch,
             "duty": self.duty, "enabled": self.enabled})

    def buffers(self) -> dict[str, Any]:
        """Its arrays by name, which a compiled servo bank (hil/servobus/servo_core.py)
        writes the servos' set-points into, and the constants it needs."""
        return {"goal": self.goal_rad, "setpoint": self.setpoint_rad,
                "speed": self.speed_limit_rad_s, "torque_limit": self.torque_limit,
                "margin": self.margin_rad, "slope": self.slope_rad, "punch": self.punch,
                "compliance": self.compliance_seen, "enabled": self.enabled,
                "duty": self.duty, "offset": self.read_offset_rad,
                "motor_no_load": self.motor.no_load_speed_rad_s,
                "position_unit": POSITION_UNIT_RAD, "punch_unit": PUNCH_FRACTION_PER_UNIT}

    def set_compliance(self, i: int, compliance: tuple[int, int, int, int, int]) -> None:
        cw_m, ccw_m, cw_s, ccw_s, punch = compliance
        self.margin_rad[:, i] = (cw_m * POSITION_UNIT_RAD, ccw_m * POSITION_UNIT_RAD)
        # a slope of 0 would be a step; the smallest real slope is 1 unit
        self.slope_rad[:, i] = (max(cw_s, 1) * POSITION_UNIT_RAD, max(ccw_s, 1) * POSITION_UNIT_RAD)
        self.punch[i] = punch * PUNCH_FRACTION_PER_UNIT
        self.compliance_seen[i] = compliance

    def control_into(self, q_rad: np.ndarray, dt_s: float, ctrl: np.ndarray) -> None:
        """Advance set-points by one step and write the motor torques (N m) into ``ctrl``
        (the world's MjData.ctrl): one compiled call a physics step."""
        self._compiled(q_rad, dt_s, ctrl, self.motor.stall_torque_nm)

    def control(self, q_rad: np.ndarray, dt_s: float) -> np.ndarray:
        """Advance set-points by one step and return the motor torques (N m) to apply."""
        return self.motor.stall_torque_nm * self.duty_for(q_rad, dt_s)

    def duty_for(self, q_rad: np.ndarray, dt_s: float) -> np.ndarray:
        """Advance set-points by one step; the signed duty on the measured angles ``q_rad``
        (``self.duty``, updated in place).

        Runs every physics step, in hil/world/drive_core.c: the set-point moves toward the
        goal by at most the speed limit's step; the duty is the error beyond the compliance
        margin over the slope, plus punch, capped at the torque limit, signed as the error,
        zero inside the margin or with torque off."""
        self._compiled(q_rad, dt_s)
        return self.duty
        sp = self.setpoint_rad
        step = self.speed_limit_rad_s * dt_s
        d = self.goal_rad - sp
        np.minimum(d, step, out=d)
        np.negative(step, out=step)
        np.maximum(d, step, out=d)
        sp += d
        e = sp - q_rad
        ccw = e > 0
        excess = np.abs(e)
        excess -= np.where(ccw, self.margin_rad[1], self.margin_rad[0])
        u = excess / np.where(ccw, self.slope_rad[1], self.slope_rad[0])
        u += self.punch
        np.minimum(u, self.torque_limit, out=u)
        u *= np.sign(e) * ((excess > 0) & self.enabled)
        self.duty[:] = u
        return self.duty


class JointWorld(Protocol):
    """What a joint needs of its world (hil/world/hexapod_world.py's HexapodWorld): its drives,
    the joint state and its clock. Declared here so this module never imports the world
    that imports it."""

    drives: DriveBank

    def joint_buffers(self) -> dict[str, Any]: ...

    def joint_state_lists(self) -> tuple[list[float], list[float], list[float]]: ...

    def advance_to(self, t_us: int) -> None: ...


class MujocoActuator:
    """One joint of the world, driven like its servo (implements the servo Actuator seam)."""

    def __init__(self, world: JointWorld, index: int) -> None:
        self.world = world
        self.index = index

    def command(self, goal_rad: float, speed_limit_rad_s: float, torque_limit_frac: float,
                enabled: bool, compliance: tuple[int, int, int, int, int] | None = None) -> None:
        bank = self.world.drives
        i = self.index
        if enabled and not bank.enabled[i]:
            bank.setpoint_rad[i] = self.state()[0]  # resume from where it reads
        bank.goal_rad[i] = goal_rad
        bank.speed_limit_rad_s[i] = speed_limit_rad_s if speed_limit_rad_s > 0 \
            else bank.motor.no_load_speed_rad_s
        bank.torque_limit[i] = min(max(torque_limit_frac, 0.0), 1.0)
        bank.enabled[i] = bool(enabled)
        if compliance is not None and compliance != tuple(bank.compliance_seen[i].tolist()):
            bank.set_compliance(i, compliance)

    def joint_buffers(self) -> tuple[dict[str, Any], int]:
        """The world's joint and drive arrays (hil/servobus/servo_core.py) and this joint's
        index in them."""
        return self.world.joint_buffers(), self.index

    def state(self) -> tuple[float, float, float]:
        """Present position (rad), speed (rad/s) and load (signed fraction of stall torque)."""
        q, qd, duty = self.world.joint_state_lists()
        i = self.index
        v = qd[i]
        load = duty[i] - v / self.world.drives.motor.no_load_speed_rad_s
        return q[i] + self.world.drives.read_offset_rad[i], v, max(-1.0, min(1.0, load))

    def advance_to(self, t_us: int) -> None:
        """Physics runs on the world's clock; asking a joint to catch up advances the world."""
        self.world.advance_to(t_us)
