"""The drive bank's compiled step (hil/world/drive_core.c) gives numpy's bits: the same
set-points, duties and torques, step after step, over random commands, compliance,
disabled joints, errors of exactly zero and inside the margins. Built by `make`
(the pinned ziglang's cc); these tests fail if it is missing, so the build is checked."""
from __future__ import annotations

import numpy as np

from hil.world import drive_core
from hil.world.actuator import POSITION_UNIT_RAD, DriveBank, motor
from protocol.dynamixel import xl430

XL430 = motor(xl430.MODEL_NAME)


def _banks(n: int, kind=None) -> tuple[DriveBank, DriveBank]:
    q0 = np.linspace(-1.0, 1.0, n)
    fast = DriveBank(q0) if kind is None else DriveBank(q0, kind)
    slow = DriveBank(q0) if kind is None else DriveBank(q0, kind)
    slow._compiled = None
    return fast, slow


def test_the_library_is_built():
    assert drive_core.available(), f"{drive_core.LIBRARY} missing: run make"


def test_the_compiled_step_is_numpys_to_the_bit():
    rng = np.random.default_rng(7)
    for kind in (None, XL430):
        fast, slow = _banks(18, kind)
        q = np.linspace(-1.0, 1.0, 18)
        ctrl_fast, ctrl_slow = np.zeros(18), np.zeros(18)
        for k in range(3000):
            if k % 10 == 0:
                i = int(rng.integers(18))
                goal = float(rng.uniform(-2.5, 2.5))
                speed = float(rng.choice([0.1, 1.0, 6.0, XL430.no_load_speed_rad_s]))
                tl = float(rng.choice([0.0, 0.3, 1.0]))
                on = bool(rng.random() < 0.9)
                comp = tuple(int(x) for x in rng.integers(0, 255, 5))
                for b in (fast, slow):
                    b.goal_rad[i], b.speed_limit_rad_s[i] = goal, speed
                    b.torque_limit[i], b.enabled[i] = tl, on
                    b.set_compliance(i, comp)
            q = q + rng.normal(0.0, 0.01, 18)
            if k % 7 == 0:   # errors of exactly zero and just inside the margin
                q[:3] = fast.setpoint_rad[:3]
                q[3:6] = fast.setpoint_rad[3:6] - 0.5 * POSITION_UNIT_RAD
            u_fast = fast.duty_for(q, 0.002).copy()
            u_slow = slow.duty_for(q, 0.002).copy()
            assert u_fast.tobytes() == u_slow.tobytes(), k
            assert fast.setpoint_rad.tobytes() == slow.setpoint_rad.tobytes(), k
            fast.control_into(q, 0.002, ctrl_fast)
            slow.control_into(q, 0.002, ctrl_slow)
            assert ctrl_fast.tobytes() == ctrl_slow.tobytes(), k
            assert fast.duty.tobytes() == slow.duty.tobytes(), k
