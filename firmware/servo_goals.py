"""Foot targets to the 18 servo goals one SYNC_WRITE sends, MicroPython-compatible.

IK of each leg (``protocol/hexapod.py``), the joint limits as AX-12 positions (written to
the servos' angle-limit registers at boot, and applied to every goal), and a Moving Speed
that lets each joint arrive within the cycle with a margin. The goal lists are reused
every cycle (no allocation in the loop).
"""
import math

from protocol.dynamixel import ax12
from protocol import hexapod
from protocol.hexapod import JOINT_ZERO

SPEED_MARGIN = 1.5          # moving-speed limit = margin x the speed the targets need
TWO_PI = 2.0 * math.pi      # ax12.rad_s_to_speed's (2.0 * math.pi), computed once
# math.degrees multiplies by 180 / pi (CPython's radToDeg, MicroPython's modmath alike):
# the same product without the call
RAD_TO_DEG = 180.0 / math.pi
SPEED_MAX = 1023            # ax12.rad_s_to_speed's upper clamp


class ServoGoals:
    """Goal Position and Moving Speed of the 18 servos, in servo-ID order."""

    def __init__(self, period_us):
        self.dt_s = period_us * 1e-6
        self.legs = [hexapod.Leg(i) for i in range(6)]
        self.neutral = [hexapod.neutral_foot(i) for i in range(6)]
        self.positions = [512] * 18
        self.speeds = [0] * 18
        self.goal_rad = [0.0] * 18
        self.limits = [(0, 1023)] * 18   # (low, high) AX-12 positions of the joint limits
        for j in range(18):
            lo, hi = self.legs[j // 3].servo_limits_rad(j % 3)
            self.limits[j] = (ax12.rad_to_position(lo), ax12.rad_to_position(hi))

    def set_leg(self, i, x, y, z, speed_rad_s):
        """Goals for leg ``i``'s foot at (x, y, z) in the body frame (m).

        ``speed_rad_s`` > 0 caps every joint's speed; 0 sets the speed that reaches the new
        goal in one cycle (times ``SPEED_MARGIN``).

        The loop's hottest lines after the IK: ``Leg.servo_rad``, ``ax12.rad_to_position``
        (its ``math.degrees`` as the product it is) and ``ax12.rad_s_to_speed`` are written
        out here with their constants bound to locals, the same operations in the same
        order, so the same bits
        (tests/test_kinematics.py compares them over the joints' range).
        """
        leg = self.legs[i]
        q = leg.ik(x, y, z)
        directions = leg.directions
        offsets = leg.offsets
        dt_s = self.dt_s
        limits = self.limits
        goal_rad = self.goal_rad
        positions = self.positions
        speeds = self.speeds
        rad_to_deg = RAD_TO_DEG
        centre_deg = ax12.POSITION_CENTRE_DEG
        position_max = ax12.POSITION_MAX
        range_deg = ax12.POSITION_RANGE_DEG
        rpm_unit = ax12.SPEED_RPM_PER_UNIT
        k = 3 * i
        for j in range(3):
            rad = directions[j] * (q[j] - JOINT_ZERO[j]) + offsets[j]
            # rad_to_position clamps to 0-1023, then to the joint's limits inside that range
            pos = round((rad * rad_to_deg + centre_deg) * position_max / range_deg)
            lo, hi = limits[k]
            positions[k] = lo if pos < lo else (hi if pos > hi else pos)
            # both speeds are >= 0: rad_s_to_speed's abs() changes no bit
            spd = speed_rad_s if speed_rad_s > 0 else SPEED_MARGIN * abs(rad - goal_rad[k]) / dt_s
            v = round(spd * 60.0 / TWO_PI / rpm_unit)
            speeds[k] = 1 if v < 1 else (SPEED_MAX if v > SPEED_MAX else v)
            goal_rad[k] = rad
            k += 1

    def clamped(self):
        """IK targets moved to the workspace's edge or the joint limits, all legs."""
        n = 0
        for leg in self.legs:
            n += leg.clamped
        return n
