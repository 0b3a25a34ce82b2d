# protocol/hexapod.py under the real micropython binary: seed 003's robot (Sec. 3.1, Fig. 12
# and 13, Eq. 15-16) and the leg kinematics the firmware and the world share.
import math

from protocol import hexapod as h
from tests.micropython.checks import check, done


def near(a, b, tol=1e-9):
    return abs(a - b) <= tol


# Fig. 12 and Sec. 3.1 figures.
check(near(h.COXA_M, 0.05) and near(h.FEMUR_M, 0.082) and near(h.TIBIA_M, 0.12), "link lengths")
check(near(h.BODY_CLEARANCE_M, 0.08), "body bottom 8 cm above ground")
check(near(h.L_MAX_M, 0.10) and near(h.H_MAX_M, 0.12), "Eq. 15 constraints")
check(near(h.STEP_LENGTH_M, 0.05), "Eq. 16: l_i = 5 cm")
check(h.LEGS == ("LF", "LM", "LH", "RF", "RM", "RH"), "Fig. 13 leg order")
check(h.SERVOS == 18 and len(h.MOUNTS) == 6 and len(h.DIRECTIONS) == 6, "18 joints, 6 legs")
check(len(h.BODY_HALF_M) == 3 and near(h.BODY_HALF_M[2] * 2, 0.03), "body box 3 cm thick")
# The whole robot in neutral stance fits the paper's 30 x 30 cm outline (sides, not legs).
for i in range(6):
    mx, my, _ = h.MOUNTS[i]
    check(abs(mx) <= 0.15 and abs(my) <= 0.15, "mount %s inside the outline" % h.LEGS[i])
    check(h.LEGS[i][0] == ("L" if my > 0 else "R"), "%s on its side" % h.LEGS[i])
# Every neutral foot stands on the ground: body bottom 8 cm up, foot sphere on the plane.
for i in range(6):
    z = h.neutral_foot(i)[2]
    check(near(-z + h.FOOT_RADIUS_M, h.BODY_CLEARANCE_M + h.BODY_HALF_M[2]), "foot %d on ground" % i)

# Fig. 13 gaits and the paper's speeds (Sec. 3.3) at the default periods.
check(h.GAITS["tripod"] == (2, (1, 0, 1, 0, 1, 0)), "tripod: LM+RF+RH first")
check(h.GAITS["wave"] == (6, (0, 1, 2, 3, 4, 5)), "wave: LF to RH")
check(h.DEFAULT_GAIT in h.GAITS and sorted(h.GAIT_PERIOD_S) == ["tripod", "wave"], "gait names")
for g, v in (("tripod", 0.036), ("wave", 0.013)):
    check(near(h.speed_m_s(g, 0.05, h.GAIT_PERIOD_S[g]), v, 1e-12), "%s at the paper's speed" % g)
check(near(h.GAIT_PERIOD_S["tripod"], 0.1 / 0.036, 1e-12), "tripod period 2.78 s")
check(near(h.GAIT_PERIOD_S["wave"], 0.3 / 0.065, 1e-12), "wave period 4.62 s")

# IK/FK round trips over the walking workspace (Eq. 15: steps up to 10 cm, 12 cm high).
worst = 0.0
for i in range(6):
    L = h.Leg(i)
    nx, ny, nz = h.neutral_foot(i)
    for dx in (-0.05, -0.02, 0.0, 0.03, 0.05):
        for dy in (-0.02, 0.0, 0.02):
            for dz in (0.0, 0.03, 0.07):
                q = L.ik(nx + dx, ny + dy, nz + dz)
                check(q is L.q, "ik reuses its list")
                f = L.fk(q[0], q[1], q[2])
                e = max(abs(f[0] - nx - dx), abs(f[1] - ny - dy), abs(f[2] - nz - dz))
                worst = e if e > worst else worst
    check(L.clamped == 0, "leg %d workspace reachable" % i)
check(worst < 1e-9, "round trip error %r" % worst)

# Neutral stance: coxa along the mount, knee above the foot's line, joints inside limits.
for i in range(6):
    L = h.Leg(i)
    q = L.ik(*h.neutral_foot(i))
    check(near(q[0], 0.0), "leg %d coxa centred" % i)
    for j in range(3):
        check(h.JOINT_MIN[j] < q[j] < h.JOINT_MAX[j], "leg %d joint %d inside limits" % (i, j))

# Out of reach: pulled onto the shell and counted, never an error.
L = h.Leg(3)
mx, my, yaw = h.MOUNTS[3]
q = L.ik(mx + 0.5 * math.cos(yaw), my + 0.5 * math.sin(yaw), -0.05)
f = L.fk(q[0], q[1], q[2])
reach = math.sqrt((f[0] - mx) ** 2 + (f[1] - my) ** 2 + f[2] ** 2)
check(reach <= h.COXA_M + h.FEMUR_M + h.TIBIA_M + 1e-6, "clamped target within reach")
L.ik(mx, my, 0.0)
check(L.clamped == 2, "two clamped targets counted")

# Servo angles: direction, zero and calibration offset round trip; limits ordered.
L = h.Leg(4, offsets=(0.01, -0.02, 0.03))
L.directions = (1, -1, 1)
for j in range(3):
    for qj in (-0.4, 0.0, 0.3):
        check(near(L.joint_rad(j, L.servo_rad(j, qj)), qj, 1e-12), "servo round trip %d" % j)
    lo, hi = L.servo_limits_rad(j)
    check(lo < hi, "limits ordered %d" % j)
check(near(h.Leg(0).servo_rad(2, h.JOINT_ZERO[2]), 0.0), "tibia zero at the servo centre")
done("hexapod")
