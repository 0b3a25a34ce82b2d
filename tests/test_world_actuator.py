"""AX-12 drive model behind the Actuator seam: compliance, limits, physics in and out."""
import math

import numpy as np
import pytest

from hexhil.hil.world import actuator as act
from hexhil.hil.scenario import parse
from hexhil.hil.world.hexapod_world import HexapodWorld

UNIT = act.POSITION_UNIT_RAD


def test_compliance_curve_margin_slope_punch_and_torque_limit():
    bank = act.DriveBank(np.zeros(4))
    bank.set_compliance(0, (2, 2, 32, 32, 0))
    bank.set_compliance(1, (2, 2, 32, 32, 0))
    bank.set_compliance(2, (2, 2, 32, 32, 100))
    bank.set_compliance(3, (0, 0, 32, 64, 0))
    bank.goal_rad[:] = [1.5 * UNIT, 18 * UNIT, 3 * UNIT, 34 * UNIT]
    bank.setpoint_rad[:] = bank.goal_rad
    bank.torque_limit[:] = [1.0, 1.0, 1.0, 0.25]
    tau = bank.control(np.zeros(4), 0.002)
    assert tau[0] == 0.0                                              # inside the margin
    assert tau[1] == pytest.approx(act.AX12.stall_torque_nm * 16 / 32)      # half-way up the slope
    assert tau[2] == pytest.approx(act.AX12.stall_torque_nm * (100 / 1023 + 1 / 32))  # punch first
    assert tau[3] == pytest.approx(act.AX12.stall_torque_nm * 0.25)        # torque limit saturates
    # CW side uses the CW slope: same error the other way, different slope
    bank.setpoint_rad[3] = bank.goal_rad[3] = -16 * UNIT
    bank.torque_limit[3] = 1.0
    assert bank.control(np.zeros(4), 0.002)[3] == pytest.approx(-act.AX12.stall_torque_nm * 0.5)


def test_set_point_moves_at_the_speed_limit_and_disabled_gives_no_torque():
    bank = act.DriveBank(np.zeros(2))
    bank.goal_rad[:] = 1.0
    bank.speed_limit_rad_s[:] = [2.0, 0.5]
    bank.enabled[1] = False
    for _ in range(100):
        tau = bank.control(np.zeros(2), 0.002)
    assert bank.setpoint_rad == pytest.approx([0.4, 0.1])
    assert tau[1] == 0.0 and tau[0] == pytest.approx(act.AX12.stall_torque_nm)


def _stand(world, t_s):
    world.advance_to(world.t_us + int(t_s * 1e6))


def test_standing_loads_come_from_physics_and_torque_off_drops_the_body():
    world = HexapodWorld(parse({"world": {}}), seed=0)
    _stand(world, 0.5)
    assert 0.07 < world.body_pose().z_m < 0.10
    femur_loads = [world.actuators()[3 * i + 1].state()[2] for i in range(6)]
    # each femur holds about a sixth of 1.5 kg at the foot's lever: a few tenths of stall
    assert all(0.03 < abs(f) < 0.6 for f in femur_loads)
    for a in world.actuators():
        q, _, _ = a.state()
        a.command(q, 0.0, 1.0, False, act.DEFAULT_COMPLIANCE)
    _stand(world, 1.0)
    assert world.body_pose().z_m < 0.05          # limp servos: the body sinks to the ground


def test_speed_limit_and_no_load_speed_in_physics():
    world = HexapodWorld(parse({"world": {}}), seed=0)
    femur = world.actuators()[4]                  # lift LM off the ground: five legs stand
    femur.command(femur.state()[0] + 0.6, 0.0, 1.0, True, act.DEFAULT_COMPLIANCE)
    _stand(world, 0.5)
    coxa = world.actuators()[3]
    q0 = coxa.state()[0]
    coxa.command(q0 + 0.4, 1.0, 1.0, True, act.DEFAULT_COMPLIANCE)
    speeds = []
    for _ in range(40):
        _stand(world, 0.01)
        speeds.append(coxa.state()[1])
    assert max(speeds) < 1.0 * 1.2                # Moving Speed bounds the motion
    assert coxa.state()[0] == pytest.approx(q0 + 0.4, abs=0.03)
    # Moving Speed 0 (no limit): the motor cannot beat its 59 rpm no-load speed
    coxa.command(q0 - 1.0, 0.0, 1.0, True, act.DEFAULT_COMPLIANCE)
    top = 0.0
    for _ in range(60):
        _stand(world, 0.004)
        top = max(top, abs(coxa.state()[1]))
    assert 0.5 * act.AX12.no_load_speed_rad_s < top <= 1.03 * act.AX12.no_load_speed_rad_s
    assert act.AX12.no_load_speed_rad_s == pytest.approx(59 * 2 * math.pi / 60)


def test_advance_to_through_an_actuator_steps_the_world():
    world = HexapodWorld(parse({"world": {}}), seed=0)
    world.actuators()[0].advance_to(10_001)
    assert world.t_us == 10_000           # whole 2 ms steps, never past the asked time
