"""Foot targets to the 18 servo goals one SYNC_WRITE sends, MicroPython-compatible.

IK of each leg (``protocol/hexapod.py``), the joint limits as AX-12 positions (written to
the servos' angle-limit registers at boot, and applied to every goal), and a Moving Speed
that lets each joint arrive within the cycle with a margin. The goal lists are reused
every cycle (no allocation in the loop).
"""
from protocol import ax12
from protocol import hexapod

SPEED_MARGIN = 1.5          # moving-speed limit = margin x the speed the targets need


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
        """
        leg = self.legs[i]
        q = leg.ik(x, y, z)
        dt_s = self.dt_s
        limits = self.limits
        goal_rad = self.goal_rad
        to_position = ax12.rad_to_position
        k = 3 * i
        for j in range(3):
            rad = leg.servo_rad(j, q[j])
            lo, hi = limits[k]
            pos = to_position(rad)
            pos = lo if pos < lo else (hi if pos > hi else pos)
            if speed_rad_s > 0:
                spd = speed_rad_s
            else:
                spd = SPEED_MARGIN * abs(rad - goal_rad[k]) / dt_s
            goal_rad[k] = rad
            self.positions[k] = pos
            self.speeds[k] = ax12.rad_s_to_speed(spd)
            k += 1

    def clamped(self):
        """IK targets moved to the workspace's edge or the joint limits, all legs."""
        n = 0
        for leg in self.legs:
            n += leg.clamped
        return n
