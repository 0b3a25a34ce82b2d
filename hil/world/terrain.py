"""Obstacle terrain for the hexapod world (seed 003, Sections 2.2 and 3.2).

Each obstacle is a half-ellipsoid resting on the ground: length L along the walking
direction (x), width W across it (y) and height H (the paper's Fig. 14 shapes). Terrain is
given explicitly in the scenario or generated from a density and a height class:

- density ``low``: centre spacing R >= 15 cm; ``high``: 10 cm < R < 15 cm (Sec. 2.2);
- height class ``small``: 3 cm <= H <= 5 cm; ``large``: 6 cm <= H <= 8 cm (Sec. 2.2);
- lengths 2-3 cm (Sec. 3.2); widths are not given by the paper (W in [0, inf], Eq. 1):
  we draw 4-10 cm, i.e. stones and sticks that block one leg at a time.

Generation is a seeded maximal Poisson-disc fill of the walking corridor, so a seed gives the
same terrain on every machine. An obstacle is either fixed to the ground (an ellipsoid half
sunk in it) or a loose body (``world.obstacle_body = "free"``): a convex half-ellipsoid mesh
with mass and floor friction that can slide, tip or be stepped on.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from hexhil.hil.scenario.world_section import Obstacle, WorldConfig
from hexhil.protocol.errors import BadValue

DENSITY_SPACING_M = {"low": (0.15, 0.25), "high": (0.10, 0.15)}  # Sec. 2.2, R ranges
HEIGHT_CLASS_M = {"small": (0.03, 0.05), "large": (0.06, 0.08)}  # Sec. 2.2, H ranges
LENGTH_RANGE_M = (0.02, 0.03)                                    # Sec. 3.2, L = 2 or 3 cm
WIDTH_RANGE_M = (0.04, 0.10)                                     # our choice, see docstring
CORRIDOR_START_M = 0.20      # first obstacle centre ahead of the start (legs clear at t=0)
CORRIDOR_HALF_WIDTH_M = 0.25  # lateral extent of the generated field (feet reach ~0.22 m)


def generate(density: str, height_class: str, length_m: float, seed: int,
             half_width_m: float = CORRIDOR_HALF_WIDTH_M) -> list[Obstacle]:
    """Fill the corridor x in [start, length_m], |y| <= half_width_m with obstacles.

    Dart throwing keeps every pair at least the class's minimum spacing apart; for ``high``
    density darts are only accepted next to the field (nearest centre under the maximum),
    so nearest-neighbour spacings stay inside the paper's 10-15 cm band.
    """
    if density not in DENSITY_SPACING_M:
        raise BadValue(f"world.density must be one of {sorted(DENSITY_SPACING_M)}, got {density!r}")
    if height_class not in HEIGHT_CLASS_M:
        raise BadValue(f"world.height_class must be one of {sorted(HEIGHT_CLASS_M)}, "
                       f"got {height_class!r}")
    if length_m <= CORRIDOR_START_M:
        raise BadValue(f"world.length_m must exceed {CORRIDOR_START_M} m, got {length_m}")
    r_min, r_max = DENSITY_SPACING_M[density]
    rng = np.random.default_rng(seed)
    centres: list[tuple[float, float]] = []
    misses = 0
    while misses < 400:
        x = float(rng.uniform(CORRIDOR_START_M, length_m))
        y = float(rng.uniform(-half_width_m, half_width_m))
        if centres:
            d = min(math.hypot(x - cx, y - cy) for cx, cy in centres)
            if d < r_min or (density == "high" and d >= r_max):
                misses += 1
                continue
        centres.append((x, y))
        misses = 0
    h_lo, h_hi = HEIGHT_CLASS_M[height_class]
    out = []
    for x, y in sorted(centres):
        out.append(Obstacle(x_m=round(x, 4), y_m=round(y, 4),
                            length_m=round(float(rng.uniform(*LENGTH_RANGE_M)), 4),
                            width_m=round(float(rng.uniform(*WIDTH_RANGE_M)), 4),
                            height_m=round(float(rng.uniform(h_lo, h_hi)), 4)))
    return out


def from_scenario(world: WorldConfig, seed: int) -> list[Obstacle]:
    """The obstacles a scenario's ``[world]`` asks for: given, generated (from the run's
    ``seed`` unless the world names its own), or none for flat ground."""
    if world.terrain == "flat":
        return []
    if world.obstacles is not None:
        return list(world.obstacles)
    return generate(world.density, world.height_class, world.length_m,
                    seed if world.terrain_seed is None else world.terrain_seed)


MESH_RINGS = 4        # elevation steps of a loose obstacle's mesh, base ring included
MESH_SECTORS = 12     # azimuth steps


def mjcf_fixed(obstacles: list[Obstacle], friction: float) -> str:
    """Worldbody geoms of obstacles fixed to the ground (ellipsoids centred on it)."""
    return "".join(
        f'\n    <geom name="obstacle{i}" type="ellipsoid" pos="{mjcf_numbers(o.x_m, o.y_m, 0)}" '
        f'size="{mjcf_numbers(o.length_m / 2, o.width_m / 2, o.height_m)}" friction="{friction}" '
        f'contype="0" conaffinity="1" rgba="0.6 0.45 0.3 1"/>'
        for i, o in enumerate(obstacles))


def mjcf_free(obstacles: list[Obstacle], friction: float,
              mass_kg: Callable[[float, float, float], float]) -> tuple[str, str]:
    """(assets, worldbody bodies) of loose obstacles: half-ellipsoid meshes on free joints.
    Their friction wins over the ground's (priority), and they collide with the robot, the
    ground and each other (contype = conaffinity = 1)."""
    assets, bodies = [], []
    for i, o in enumerate(obstacles):
        a, b, c = o.length_m / 2, o.width_m / 2, o.height_m
        verts = []
        for k in range(MESH_RINGS + 1):
            el = 0.5 * math.pi * k / MESH_RINGS
            for j in range(MESH_SECTORS if k < MESH_RINGS else 1):
                az = 2 * math.pi * j / MESH_SECTORS
                verts += [a * math.cos(el) * math.cos(az), b * math.cos(el) * math.sin(az),
                          c * math.sin(el)]
        assets.append(f'\n    <mesh name="obstacle{i}" vertex="{mjcf_numbers(*verts)}"/>')
        bodies.append(
            f'\n    <body name="obstacle{i}" pos="{mjcf_numbers(o.x_m, o.y_m, 0)}"><freejoint/>'
            f'<geom name="obstacle{i}" type="mesh" mesh="obstacle{i}" '
            f'mass="{mass_kg(o.length_m, o.width_m, o.height_m):.6g}" friction="{friction}" '
            f'priority="1" contype="1" conaffinity="1" rgba="0.6 0.45 0.3 1"/></body>')
    return "".join(assets), "".join(bodies)


def mjcf_numbers(*v: float) -> str:
    return " ".join(f"{x:.6g}" for x in v)
