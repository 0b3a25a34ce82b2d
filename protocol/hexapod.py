"""The robot description of seed 003's hexapod, read by the firmware and the simulated world.

Seed 003 Sec. 3.1 and Fig. 12: 1.5 kg, about 30 x 30 cm, coxa 5 cm, femur 8.2 cm, tibia
12 cm, body bottom 8 cm above the ground in the neutral stance, 18 AX-12 joints; Fig. 13:
the tripod and wave gaits. Where the paper is silent (mounts, body box, joint limits) the
values are our choice and say so. MicroPython-compatible (no annotations, no numpy).

Body frame: x forward, y left, z up, origin at the body centre, on the plane of the coxa
joints (the body box's mid-plane). In neutral stance the foot (tibia end) is
``STANCE_DEPTH_M`` below that plane. Leg frame: origin at the coxa joint, x radially out
along the mounting yaw, z up.

Joint angles (rad): coxa yaw q1, femur pitch q2 (0 = horizontal, up positive), tibia q3
relative to the femur (0 = straight, negative bends the foot down). Servo angles are
``direction * (q - zero) + offset``, 0 rad at the AX-12's centre (512); the world's MuJoCo
joints take servo angles.
"""
import math

# Leg order everywhere: servo IDs (leg i has coxa 3i+1, femur 3i+2, tibia 3i+3), CAN
# tactile bit i = leg i; Fig. 13's abbreviations.
LEGS = ("LF", "LM", "LH", "RF", "RM", "RH")
JOINTS = ("coxa", "femur", "tibia")
SERVOS = 3 * len(LEGS)

COXA_M = 0.05    # Fig. 12
FEMUR_M = 0.082  # Fig. 12
TIBIA_M = 0.12   # Fig. 12, knee to the foot sphere's centre
BODY_CLEARANCE_M = 0.08      # Fig. 12: ground to body bottom, neutral stance
# Body box half-extents (our choice inside the 30 x 30 cm outline, Sec. 3.1); the coxa
# joints lie on its mid-plane.
BODY_HALF_M = (0.11, 0.065, 0.015)
FOOT_RADIUS_M = 0.01
STANCE_DEPTH_M = BODY_CLEARANCE_M + BODY_HALF_M[2] - FOOT_RADIUS_M
L_MAX_M = 0.10   # Eq. 15: longest step
H_MAX_M = 0.12   # Eq. 15: highest step

# Mounting poses (x_m, y_m, yaw_rad) in leg order. The paper gives only the 30 x 30 cm
# outline "including front and rear legs angle offsets and middle legs displacements";
# our choice: corners at 45 deg, middle legs on the sides.
_D45 = math.pi / 4
MOUNTS = (
    (0.10, 0.06, _D45),
    (0.0, 0.075, 2 * _D45),
    (-0.10, 0.06, 3 * _D45),
    (0.10, -0.06, -_D45),
    (0.0, -0.075, -2 * _D45),
    (-0.10, -0.06, -3 * _D45),
)
# Neutral foot: this far from the coxa joint along the mounting yaw, on the ground.
NEUTRAL_REACH_M = 0.15

# Joint zero (the angle that maps to the servo centre) and limits, in joint angles.
JOINT_ZERO = (0.0, 0.0, -math.pi / 2)
JOINT_MIN = (-1.2, -1.6, -2.9)
JOINT_MAX = (1.2, 2.3, 0.0)
# Servo direction per joint (+1: servo angle turns with the joint). The simulated robot
# mounts every servo the same way; a real build sets -1 where a horn is mirrored.
DIRECTIONS = ((1, 1, 1),) * 6

_REACH_MAX = FEMUR_M + TIBIA_M - 1e-6
_REACH_MIN = abs(TIBIA_M - FEMUR_M) + 1e-6
# The law of cosines' constant products, as Leg.ik's formulas group them.
_FEMUR_SQ_M2 = FEMUR_M * FEMUR_M
_TIBIA_SQ_M2 = TIBIA_M * TIBIA_M
_LINKS_SQ_M2 = _FEMUR_SQ_M2 + _TIBIA_SQ_M2
_TWO_FEMUR_M = 2 * FEMUR_M
_TWO_FEMUR_TIBIA_M2 = 2 * FEMUR_M * TIBIA_M

# Gaits (Fig. 13): name -> (period T in leg transfers, lift-off phase of each leg in LEGS
# order). Tripod: LM+RF+RH in the first half of the period, LF+LH+RM in the second; wave:
# one leg at a time, LF to RH.
GAITS = {
    "tripod": (2, (1, 0, 1, 0, 1, 0)),
    "wave": (6, (0, 1, 2, 3, 4, 5)),
}
DEFAULT_GAIT = "tripod"
STEP_LENGTH_M = 0.05  # l_i: Eq. 1 and 16, L <= l_i = 5 cm
GAIT_SPEED_M_S = {"tripod": 0.036, "wave": 0.013}  # Sec. 3.3


def speed_m_s(gait, step_length_m, period_s):
    """Body speed of ``gait``: a stance foot sweeps l in T - 1 of the T units (Eq. 2-3)."""
    T = GAITS[gait][0]
    return step_length_m * T / ((T - 1) * period_s)


def period_for_speed_s(gait, step_length_m, v_m_s):
    """The gait period (s) that walks ``gait`` at ``v_m_s`` (inverse of ``speed_m_s``)."""
    T = GAITS[gait][0]
    return step_length_m * T / ((T - 1) * v_m_s)


def periods_for_distance(distance_m, v_m_s, period_s):
    """Sec. 3.3's "steps needed to reach the goal": whole gait periods that walk
    ``distance_m`` at ``v_m_s`` (at least one)."""
    return max(1, round(distance_m / (v_m_s * period_s)))


# The periods that give the paper's speeds at l_i (tripod 2.78 s, wave gait 4.62 s).
GAIT_PERIOD_S = {g: period_for_speed_s(g, STEP_LENGTH_M, GAIT_SPEED_M_S[g]) for g in GAITS}


def neutral_foot(leg):
    """Neutral foot position of ``leg`` in the body frame (m)."""
    mx, my, yaw = MOUNTS[leg]
    return (mx + NEUTRAL_REACH_M * math.cos(yaw), my + NEUTRAL_REACH_M * math.sin(yaw),
            -STANCE_DEPTH_M)


class Leg:
    """One leg's IK/FK with calibration; counts clamped targets instead of failing."""

    def __init__(self, index, offsets=(0.0, 0.0, 0.0)):
        self.index = index
        mx, my, yaw = MOUNTS[index]
        self.mx = mx
        self.my = my
        self.yaw = yaw
        self.c = math.cos(yaw)
        self.s = math.sin(yaw)
        self.offsets = offsets
        self.directions = DIRECTIONS[index]
        self.clamped = 0          # targets moved to the edge of the workspace or limits
        self.q = [0.0, 0.0, 0.0]  # last IK solution (joint angles, rad)

    def ik(self, x, y, z):
        """Joint angles for a foot at (x, y, z) in the body frame; stored in ``self.q``.

        Out-of-reach targets are pulled onto the reachable shell and joint angles clamped to
        the limits; either counts once in ``clamped``. Returns ``self.q`` (no allocation).
        The firmware's hottest function: names are bound to locals and the link-length
        products precomputed (the same operations in the same order, so the same bits).
        """
        c = self.c
        s = self.s
        dx = x - self.mx
        dy = y - self.my
        lx = c * dx + s * dy   # leg frame
        ly = -s * dx + c * dy
        sqrt = math.sqrt
        q1 = math.atan2(ly, lx)
        r = sqrt(lx * lx + ly * ly) - COXA_M
        d = sqrt(r * r + z * z)
        clamped = False
        if d > _REACH_MAX or d < _REACH_MIN:
            clamped = True
            target = _REACH_MAX if d > _REACH_MAX else _REACH_MIN
            if d < 1e-9:
                r, z, d = target, 0.0, target
            else:
                r = r * target / d
                z = z * target / d
                d = target
        dd = d * d
        a = (_FEMUR_SQ_M2 + dd - _TIBIA_SQ_M2) / (_TWO_FEMUR_M * d)
        b = (_LINKS_SQ_M2 - dd) / _TWO_FEMUR_TIBIA_M2
        a = 1.0 if a > 1.0 else (-1.0 if a < -1.0 else a)
        b = 1.0 if b > 1.0 else (-1.0 if b < -1.0 else b)
        q2 = math.atan2(z, r) + math.acos(a)   # knee up
        q3 = math.acos(b) - math.pi
        q = self.q
        q[0] = q1
        q[1] = q2
        q[2] = q3
        for j in range(3):
            v = q[j]
            if v < JOINT_MIN[j]:
                q[j] = JOINT_MIN[j]
                clamped = True
            elif v > JOINT_MAX[j]:
                q[j] = JOINT_MAX[j]
                clamped = True
        if clamped:
            self.clamped += 1
        return q

    def fk(self, q1, q2, q3):
        """Foot position (x, y, z) in the body frame for joint angles (rad)."""
        r = COXA_M + FEMUR_M * math.cos(q2) + TIBIA_M * math.cos(q2 + q3)
        z = FEMUR_M * math.sin(q2) + TIBIA_M * math.sin(q2 + q3)
        lx = r * math.cos(q1)
        ly = r * math.sin(q1)
        return (self.mx + self.c * lx - self.s * ly, self.my + self.s * lx + self.c * ly, z)

    def servo_rad(self, j, q):
        """Joint angle -> servo angle (0 at the AX-12 centre) with direction and offset."""
        return self.directions[j] * (q - JOINT_ZERO[j]) + self.offsets[j]

    def joint_rad(self, j, servo):
        """Servo angle -> joint angle (inverse of ``servo_rad``)."""
        return (servo - self.offsets[j]) * self.directions[j] + JOINT_ZERO[j]

    def servo_limits_rad(self, j):
        """(low, high) servo angles that the joint limits map to."""
        a = self.servo_rad(j, JOINT_MIN[j])
        b = self.servo_rad(j, JOINT_MAX[j])
        return (a, b) if a < b else (b, a)
