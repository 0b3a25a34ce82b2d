"""Obstacle terrain: seed 003's size classes and densities (Sec. 2.2, 3.2), seeded."""
import itertools
import math

import pytest

from hexhil.hil.world import terrain
from hexhil.hil import scenario
from hexhil.protocol.errors import UserError
from conftest import ROOT


def _nearest(obs):
    return [min(math.hypot(a.x_m - b.x_m, a.y_m - b.y_m) for b in obs if b is not a) for a in obs]


@pytest.mark.parametrize("density,height_class", list(itertools.product(["low", "high"], ["small", "large"])))
def test_generated_terrain_matches_the_paper_classes(density, height_class):
    obs = terrain.generate(density, height_class, 1.3, seed=7)
    r_lo, r_hi = terrain.DENSITY_SPACING_M[density]
    h_lo, h_hi = terrain.HEIGHT_CLASS_M[height_class]
    assert len(obs) >= 8
    near = _nearest(obs)
    assert min(near) >= r_lo - 1e-3                 # low: R >= 15 cm; high: R > 10 cm
    if density == "high":
        assert max(near) < r_hi                     # high: R < 15 cm
    for o in obs:
        assert h_lo - 1e-4 <= o.height_m <= h_hi + 1e-4
        assert 0.02 - 1e-4 <= o.length_m <= 0.03 + 1e-4
        assert terrain.CORRIDOR_START_M <= o.x_m <= 1.3
        assert abs(o.y_m) <= terrain.CORRIDOR_HALF_WIDTH_M


def test_high_density_has_more_obstacles_and_seeds_are_reproducible():
    low = terrain.generate("low", "small", 1.3, seed=3)
    high = terrain.generate("high", "small", 1.3, seed=3)
    assert len(high) > 1.5 * len(low)
    assert terrain.generate("low", "small", 1.3, seed=3) == low
    assert terrain.generate("low", "small", 1.3, seed=4) != low


def test_scenarios_shipped_load_and_generate():
    for d, h in itertools.product(["low", "high"], ["small", "large"]):
        sc = scenario.load_scenario(ROOT / "scenarios" / f"obstacles-{d}-{h}.toml")
        obs = terrain.from_scenario(sc.world, sc.scenario.seed)
        assert obs == terrain.generate(d, h, sc.world.length_m, sc.scenario.seed)


def test_explicit_obstacles_and_flat_ground():
    world = scenario.parse({"world": {"terrain": "obstacles", "obstacles": [
        {"x_m": 0.3, "y_m": 0.1, "length_m": 0.02, "width_m": 0.05, "height_m": 0.04}]}}).world
    assert terrain.from_scenario(world, 0) == [terrain.Obstacle(0.3, 0.1, 0.02, 0.05, 0.04)]
    assert terrain.from_scenario(scenario.parse({"world": {}}).world, 0) == []
    # terrain_seed pins the field while the run seed varies
    world = scenario.parse({"world": {"terrain": "obstacles", "terrain_seed": 5}}).world
    assert terrain.from_scenario(world, 1) == terrain.from_scenario(world, 2)
    # generated terrain runs 0.3 m past the gait's goal unless the world gives its length
    assert scenario.parse({"world": {}, "gait": {"distance_m": 2.0}}).world.length_m == 2.3
    assert scenario.parse({"world": {"length_m": 0.9}}).world.length_m == 0.9


@pytest.mark.parametrize("world,msg", [
    ({"terrain": "rocks"}, "world.terrain"),
    ({"terrain": "obstacles", "density": "medium"}, "world.density"),
    ({"terrain": "obstacles", "height_class": "huge"}, "world.height_class"),
    ({"terrain": "obstacles", "obstacles": [{"x_m": 1}]}, "world.obstacles[0]"),
    ({"terrain": "obstacles", "obstacles": [{"x_m": 0.3, "y_m": 0, "length_m": 0.02, "width_m": 0.05,
                                               "height_m": -1}]}, "positive"),
    ({"obstacles": []}, "world.terrain"),
])
def test_bad_terrain_keys_are_user_errors(world, msg):
    with pytest.raises(UserError, match=msg.replace("[", r"\[").replace("]", r"\]")):
        scenario.parse({"world": world}, "x.toml")
