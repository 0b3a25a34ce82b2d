"""The ``[world]`` section as a frozen type: which world, its ground, its obstacles (given
or generated) and its fidelity, every default and rule here; hil/world/ builds from it."""
from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Any

from hexhil.hil.scenario.rules import check_table, one_of, positive
from hexhil.protocol.errors import BadValue

TERRAINS = ("flat", "obstacles")
DENSITIES = ("low", "high")          # hil/world/terrain.py: the spacing of each (Sec. 2.2)
HEIGHT_CLASSES = ("small", "large")  # hil/world/terrain.py: the heights of each (Sec. 2.2)
MODELS = ("ideal", "real")           # hil/world/fidelity.py
OBSTACLE_BODIES = ("fixed", "free")
OBSTACLE_BODY = "fixed"              # the default, with ``real`` too (paper Sec. 4: fidelity.py)
GOAL_MARGIN_M = 0.3                  # generated terrain runs this far past the goal
DEFAULT_GOAL_M = 1.0                 # the goal ahead when the gait names none


class WorldKind(str, Enum):
    HEXAPOD = "hexapod"   # the MuJoCo hexapod (hil/world/hexapod_world.py), driven by the firmware
    BEAMS = "beams"       # seed 000's two beams (hil/world/beams.py), stepped by the simulator


@dataclass(frozen=True)
class Obstacle:
    """A half-ellipsoid on the ground, centre (x_m, y_m), full extents L, W and height H."""

    x_m: float
    y_m: float
    length_m: float
    width_m: float
    height_m: float


_OBSTACLE_FIELDS = {k: (float, True) for k in ("x_m", "y_m", "length_m", "width_m", "height_m")}


def _obstacles(where: str, items: list[Any]) -> tuple[Obstacle, ...]:
    out = []
    for i, item in enumerate(items):
        if not isinstance(item, dict):
            raise BadValue(f"{where}: world.obstacles[{i}] must be a table with exactly "
                           f"{', '.join(sorted(_OBSTACLE_FIELDS))}")
        o = Obstacle(**check_table(where, item, _OBSTACLE_FIELDS, f"world.obstacles[{i}]."))
        if min(o.length_m, o.width_m, o.height_m) <= 0:
            raise BadValue(f"{where}: world.obstacles[{i}] sizes must be positive")
        out.append(o)
    return tuple(out)


@dataclass(frozen=True)
class WorldConfig:
    """``kind`` None: no world (kinematic servos); a ``[world]`` without ``kind`` is the
    hexapod. ``obstacles`` None: generated from density and height class when the terrain
    is "obstacles"; the seeds None: the run's seed."""

    kind: WorldKind | None = None
    terrain: str = "flat"
    density: str = "low"
    height_class: str = "small"
    obstacles: tuple[Obstacle, ...] | None = None
    length_m: float = DEFAULT_GOAL_M + GOAL_MARGIN_M
    friction: float = 1.0
    terrain_seed: int | None = None
    model: str = "ideal"           # "ideal" (regression) or "real" (hil/world/fidelity.py)
    obstacle_body: str = OBSTACLE_BODY
    units_seed: int | None = None

    @property
    def ideal(self) -> bool:
        return self.model == "ideal"

    @classmethod
    def parse(cls, where: str, d: dict[str, Any], goal_m: float | None) -> "WorldConfig":
        """``goal_m``: the gait's distance, which generated terrain runs past."""
        length_m = (DEFAULT_GOAL_M if goal_m is None else goal_m) + GOAL_MARGIN_M
        if not d:
            return cls(length_m=length_m)
        kind = d.get("kind", WorldKind.HEXAPOD.value)
        try:
            values: dict[str, Any] = {**d, "kind": WorldKind(kind)}
        except ValueError:
            raise BadValue(f"{where}: key 'world.kind' must be one of "
                           f"{', '.join(k.value for k in WorldKind)}, got {kind!r}") from None
        if "obstacles" in d:
            values["obstacles"] = _obstacles(where, d["obstacles"])
        values.setdefault("length_m", length_m)
        w = cls(**values)
        if w.terrain == "flat" and w.obstacles is not None:
            raise BadValue(f"{where}: world.obstacles needs world.terrain = \"obstacles\"")
        if w.terrain not in TERRAINS:
            raise BadValue(f"{where}: world.terrain must be \"flat\" or \"obstacles\", "
                           f"got {w.terrain!r}")
        one_of(f"{where}: key 'world.density'", w.density, DENSITIES)
        one_of(f"{where}: key 'world.height_class'", w.height_class, HEIGHT_CLASSES)
        positive(f"{where}: key 'world.friction'", w.friction)
        if w.model not in MODELS:
            raise BadValue(f"{where}: key 'world.model' must be ideal or real, got {w.model!r}")
        if w.obstacle_body not in OBSTACLE_BODIES:
            raise BadValue(f"{where}: key 'world.obstacle_body' must be fixed or free, "
                           f"got {w.obstacle_body!r}")
        if w.ideal and (w.obstacle_body == "free" or w.units_seed is not None):
            raise BadValue(f"{where}: world.obstacle_body = \"free\" and world.units_seed "
                           f"need world.model = \"real\"")
        return w
