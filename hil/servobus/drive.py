"""The seam between an emulated AX-12A and what turns its horn, and the kinematic drive.

``Servo`` (hil/servobus/ax12_servo.py) hands its actuator the set-point in SI units (``drive``: Goal
Position clamped to the angle limits, Moving Speed, Torque Limit, Torque Enable and the
compliance registers) and reads Present Position, Speed and Load back from ``state()``.
``KinematicActuator`` is the drive without physics; the hexapod world's MuJoCo joints
(hil/world/actuator.py) are the other.
"""
from __future__ import annotations

import math

from hexhil.hil.seams import Actuator
from hexhil.hil.servobus.servo_layout import MOVING_EPS_RAD_S, NO_LOAD_RAD_S


def is_moving(velocity_rad_s: float) -> bool:
    """The Moving flag's rule: turning faster than half a Present Speed unit."""
    return abs(velocity_rad_s) >= MOVING_EPS_RAD_S


def drive(actuator: Actuator, setpoint: tuple[float, float, float, bool,
                                               tuple[int, int, int, int, int]]) -> None:
    """Hand an AX-12 control table's set-point (servo_rules.py ``ServoCalls.setpoint``:
    goal, speed limit, torque limit, Torque Enable, compliance) to ``actuator``; a goal of
    NaN holds the horn where it reads.

    Joint mode stops the horn at the angle limits; wheel mode turns endlessly (speed 0
    stops it where it is). A DC motor's no-load speed and stall torque scale with its
    supply (rated at 12 V), so speed and torque limits shrink with it.
    """
    goal_rad, speed_rad_s, torque_frac, enabled, compliance = setpoint
    if goal_rad != goal_rad:
        goal_rad = actuator.state()[0]
    actuator.command(goal_rad, speed_rad_s, torque_frac, enabled, compliance)


class KinematicActuator:
    """Moves towards the goal at the speed limit; no forces, no inertia.

    The speed saturates at the motor's no-load speed (``ax12.speed_to_rad_s(0)``), so
    Moving Speed above that, like 0, runs flat out.

    An infinite goal (wheel mode) turns endlessly, the angle wrapping to [-pi, pi).
    Holds still with torque off or a zero torque limit. ``stalled`` (set by the stall
    fault) models an external load that blocks the horn: it stays put and reports a load
    equal to the torque limit, which is what trips the overload alarm on a real servo.
    """

    __slots__ = ("position_rad", "velocity_rad_s", "load_frac", "goal_rad", "speed_rad_s",
                 "torque_frac", "enabled", "stalled", "t_us")

    def __init__(self, position_rad: float = 0.0, t_us: int = 0) -> None:
        self.position_rad = position_rad
        self.velocity_rad_s = 0.0
        self.load_frac = 0.0
        self.goal_rad = position_rad
        self.speed_rad_s = NO_LOAD_RAD_S
        self.torque_frac = 1.0
        self.enabled = False
        self.stalled = False
        self.t_us = t_us

    def command(self, goal_rad: float, speed_limit_rad_s: float, torque_limit_frac: float,
                enabled: bool, compliance: tuple[int, int, int, int, int]) -> None:
        self.goal_rad = goal_rad
        self.speed_rad_s = min(speed_limit_rad_s, NO_LOAD_RAD_S)
        self.torque_frac = torque_limit_frac
        self.enabled = enabled  # compliance shapes force; without forces it changes nothing
        self._settle()

    def _settle(self) -> None:
        err = self.goal_rad - self.position_rad
        driving = self.enabled and self.torque_frac > 0.0 and abs(err) > 1e-12
        if not driving:
            self.velocity_rad_s = 0.0
            self.load_frac = 0.0
        elif self.stalled:
            self.velocity_rad_s = 0.0
            self.load_frac = self.torque_frac if err > 0 else -self.torque_frac
        else:
            self.velocity_rad_s = self.speed_rad_s if err > 0 else -self.speed_rad_s
            self.load_frac = 0.0

    def state(self) -> tuple[float, float, float]:
        return self.position_rad, self.velocity_rad_s, self.load_frac

    def advance_to(self, t_us: int) -> None:
        """Exact over the interval: constant speed until the goal, then hold."""
        dt_us = t_us - self.t_us
        if dt_us <= 0:
            return
        self.t_us = t_us
        if self.velocity_rad_s == 0.0:
            return
        err = self.goal_rad - self.position_rad
        step = abs(self.velocity_rad_s) * dt_us * 1e-6
        if step >= abs(err):
            self.position_rad = self.goal_rad
        else:
            self.position_rad += step if err > 0 else -step
        if math.isinf(self.goal_rad):  # wheel mode: the horn turns round and round
            self.position_rad = (self.position_rad + math.pi) % (2.0 * math.pi) - math.pi
        self._settle()

    def set_stalled(self, stalled: bool) -> None:
        self.stalled = stalled
        self._settle()
