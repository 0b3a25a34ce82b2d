"""The real world model: off by default, seeded, and physically different."""
import math

import pytest

from hexhil.hil.scenario import parse
from hexhil.hil.world.hexapod_world import HexapodWorld
from hexhil.protocol.errors import UserError


def _world(model: str, seed: int = 1, **world) -> HexapodWorld:
    return HexapodWorld(parse({"world": {"kind": "hexapod", "model": model, **world}}), seed)


def _swing(world: HexapodWorld, steps: int = 150) -> list[float]:
    acts = world.actuators()
    q0 = [a.state()[0] for a in acts]
    for k in range(steps):
        for i, a in enumerate(acts):
            a.command(q0[i] + 0.3 * math.sin(2 * math.pi * k / 50), 0.0, 1.0, True, (1, 1, 32, 32, 32))
        world.advance_to((k + 1) * 20_000)
    return world.joint_positions().tolist()


def test_ideal_is_the_default_and_real_keys_need_real():
    assert _world("ideal").real is None
    with pytest.raises(UserError, match="world.model"):
        _world("fancy")
    with pytest.raises(UserError, match="need world.model"):
        _world("ideal", obstacle_body="free")


def test_units_are_the_same_robot_and_trials_differ_by_seed():
    a, b = _world("real", 1, units_seed=0), _world("real", 2, units_seed=0)
    assert (a.real.offsets_rad == b.real.offsets_rad).all()
    assert (a.real.stall_nm == b.real.stall_nm).all() and a.real.stall_nm.max() <= 1.375 * 1.1 + 1e-9
    assert (a.real.foot_friction != b.real.foot_friction).any()
    assert _swing(a) != _swing(b)                       # repeated trials differ
    assert _swing(_world("ideal", 1)) == _swing(_world("ideal", 2))


def test_present_position_reads_the_potentiometer_offset():
    w = _world("real", 3)
    a = w.actuators()[4]
    assert a.state()[0] == pytest.approx(w.joint_positions()[4] + w.real.offsets_rad[4])


def test_loose_obstacles_are_free_bodies_that_move_when_pushed():
    obstacle = {"x_m": 0.0, "y_m": 0.0, "length_m": 0.03, "width_m": 0.08, "height_m": 0.04}
    free = _world("real", terrain="obstacles", obstacles=[obstacle], obstacle_body="free")
    fixed = _world("real", terrain="obstacles", obstacles=[obstacle])   # the default
    assert free.real.free_obstacles and not fixed.real.free_obstacles
    assert free.model.nq == fixed.model.nq + 7
    body = free.model.body("obstacle0").id
    assert free.model.body_mass[body] == pytest.approx(600 * 2 / 3 * math.pi * 0.015 * 0.04 * 0.04)
