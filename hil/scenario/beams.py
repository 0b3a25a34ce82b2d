"""Seed 000's sections (world.kind = "beams"): the two beams (Sec. II-B, Eq. 6's force
sensor) and the host side's traversal (Sec. III), with their defaults and rules."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from hexhil.protocol.errors import BadValue

STRATEGIES = ("interact", "avoid", "none")
METHODS = ("fast", "paper")
FX_LIMIT_N = 2.0        # the actuator's limit |F_x| (Sec. III-D)
MAX_TIME_S = 8.0        # after first contact: a traversal takes at most this long


@dataclass(frozen=True)
class BeamsConfig:
    k1_nm_per_rad: float = 0.0
    k2_nm_per_rad: float = 0.0
    hb1_m: float = 0.0
    hb2_m: float = 0.0      # defaults to hb1_m
    noise: float = 0.2
    preload_nm: float = 0.0
    mass_kg: float = 0.0

    @classmethod
    def parse(cls, where: str, d: dict[str, Any], required: bool) -> "BeamsConfig":
        """``required``: the scenario's world is the beams, so both stiffnesses are needed."""
        if required:
            for key in ("k1_nm_per_rad", "k2_nm_per_rad"):
                if key not in d:
                    raise BadValue(f"{where}: world.kind 'beams' needs key 'beams.{key}'")
        for key, value in d.items():
            if not (math.isfinite(value) and value >= 0):
                raise BadValue(f"{where}: key 'beams.{key}' must be a finite number >= 0, "
                               f"got {value}")
        return cls(**{"hb2_m": d.get("hb1_m", 0.0), **d})


@dataclass(frozen=True)
class TraversalConfig:
    strategy: str = "interact"
    fx_n: float = 0.0        # defaults to 1 N without interaction, else 0.1 N
    delay_ms: float = 300.0
    sensing_ms: float = 300.0
    unknowns: int = 3        # Sec. III-C uses three unknowns at 20 % noise
    method: str = "fast"
    max_time_s: float = MAX_TIME_S

    @classmethod
    def parse(cls, where: str, d: dict[str, Any]) -> "TraversalConfig":
        strategy = d.get("strategy", "interact")
        if strategy not in STRATEGIES:
            raise BadValue(f"{where}: key 'traversal.strategy' must be one of "
                           f"{', '.join(STRATEGIES)}, got {strategy!r}")
        t = cls(**{"fx_n": 1.0 if strategy == "none" else 0.1, **d})
        if t.method not in METHODS:
            raise BadValue(f"{where}: key 'traversal.method' must be fast or paper")
        if t.unknowns not in (2, 3, 4):
            raise BadValue(f"{where}: key 'traversal.unknowns' must be 2, 3 or 4")
        if abs(t.fx_n) > FX_LIMIT_N:
            raise BadValue(f"{where}: key 'traversal.fx_n' must be within the actuator limit "
                           f"|F_x| <= 2 N, got {t.fx_n}")
        return t
