"""A scenario's sections as typed, frozen objects: each section's defaults and rules beside
its type, applied once when a scenario is loaded (hil/scenario/__init__.py).

Keys a section leaves to the firmware (``firmware/config.py``: cycle rate, tactile rule,
servo loss time) or to the world (``hil/world``: terrain, model) stay None here when the
file does not set them: their defaults live with their owner, on the other floor.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum
from typing import Any

from protocol import hexapod
from protocol.dynamixel import ax12, models
from protocol.errors import UserError

DEFAULT_DURATION_S = 30.0
# Trace timestamps are u64 nanoseconds (MCAP log_time): 1.8e10 s; a run is kept well inside.
MAX_DURATION_S = 1e9
DEFAULT_SERVOS = 18              # protocol/hexapod.py: 6 legs x 3 joints
DEFAULT_FIRST_ID = 1
DEFAULT_BAUD = 1_000_000         # the AX-12's factory rate (register 4 = 1)
RETURN_DELAY_MAX_US = 508        # AX-12 register 5: 2 us a unit, 0-254
SERVO_MODELS = tuple(models.MODELS)   # protocol/dynamixel/models.py
SENSOR_NODE_PROTOCOL = 1         # the limit-switch node (hil/servobus/switch_node.py) speaks 1.0
GAITS = tuple(hexapod.GAITS)     # tripod, wave
DEFAULT_GAIT = hexapod.DEFAULT_GAIT
# Every number a scenario, a flag or an argument takes has a physical range (docs/api.md):
SEED_MAX = 2**32 - 1             # the RNGs' seed (numpy SeedSequence, MuJoCo terrain): 32 bits
PERIOD_S = (0.1, 60.0)           # a gait cycle: at least 5 of the firmware's 20 ms cycles
STEP_LENGTH_M = (0.0, 0.2)       # within the leg's reach (coxa 5 + femur 8.2 + tibia 12 cm)
STEP_HEIGHT_M = (0.0, 0.15)
OBSTACLE_HEIGHT_M = (0.0, 0.15)
DIRECTION_DEG = (-360.0, 360.0)
DISTANCE_M = (0.0, 1000.0)       # a goal ahead (0: none; the experiments' probe)
CYCLE_HZ = (0.0, 1000.0)         # the firmware's control rate (above 0)
SERVO_LOST_S = (0.0, 3600.0)     # (above 0)
READS_PER_CYCLE = (0, 254)
RATE = (0.0, 1.0)                # a fault's probability


class Runtime(str, Enum):
    """Where the firmware runs: the micropython binary (the reference), CPython in a child
    process, or CPython in this process (sweeps: same frames, same digest)."""

    MICROPYTHON = "micropython"
    CPYTHON = "cpython"
    CPYTHON_INPROCESS = "cpython-inprocess"

    @classmethod
    def parse(cls, value: str, what: str) -> "Runtime":
        """``value`` as a runtime; ``what`` names the key or flag in the one-line refusal."""
        try:
            return cls(value)
        except ValueError:
            raise UserError(f"{what} must be one of {', '.join(r.value for r in cls)}, "
                            f"got {value!r}") from None


class WorldKind(str, Enum):
    HEXAPOD = "hexapod"   # the MuJoCo hexapod (hil/world/hexapod.py), driven by the firmware
    BEAMS = "beams"       # seed 000's two beams (hil/world/beams.py), stepped by the simulator


def check_number(value: Any, what: str, low: float, high: float, unit: str = "", *,
                 above: bool = False) -> float:
    """The one check of a number given to hexhil (a scenario key, a flag, an argument): a
    finite number from ``low`` (excluded with ``above``) to ``high``; else one line naming
    ``what`` (``UserError``)."""
    ok = (isinstance(value, (int, float)) and not isinstance(value, bool)
          and math.isfinite(value) and (value > low if above else value >= low)
          and value <= high)
    if not ok:
        lo = f"above {low:g}" if above else f"from {low:g}"
        raise UserError(f"{what} must be a finite number {lo} to {high:g}{unit}, got {value!r}")
    return float(value)


def check_seed(value: Any, what: str) -> int:
    """A seed: an integer from 0 to ``SEED_MAX`` (the RNGs take 32 bits)."""
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= SEED_MAX:
        raise UserError(f"{what} must be an integer from 0 to {SEED_MAX} (2**32 - 1), "
                        f"got {value!r}")
    return value


def check_span(start_s: float | None, end_s: float | None) -> None:
    """A stretch of a trace (``--start``/``--end``, seconds from its start; None: open):
    finite, within a trace's clock, and not empty."""
    for value, what in ((start_s, "--start"), (end_s, "--end")):
        if value is not None:
            check_number(value, what, 0.0, MAX_DURATION_S, " s")
    if start_s is not None and end_s is not None and not start_s < end_s:
        raise UserError(f"--start {start_s:g} s is not before --end {end_s:g} s: the range "
                        "is empty")


def check_duration(value: float, what: str) -> float:
    """A run's length in seconds: positive, finite and within ``MAX_DURATION_S`` (a trace's
    clock is u64 nanoseconds)."""
    return check_number(value, what, 0.0, MAX_DURATION_S, " s", above=True)


def _check_keys(where: str, section: str, values: Any,
                ranges: dict[str, tuple[tuple[float, float], str, bool]]) -> None:
    """Each key of ``ranges`` that ``values`` sets (not None): ``check_number``'s range,
    unit and whether the low end is excluded."""
    for key, ((low, high), unit, above) in ranges.items():
        v = getattr(values, key)
        if v is not None:
            check_number(v, f"{where}: key '{section}.{key}'", low, high, unit, above=above)


@dataclass(frozen=True)
class ScenarioInfo:
    name: str = ""
    description: str = ""
    seed: int = 0
    duration_s: float = DEFAULT_DURATION_S

    @classmethod
    def parse(cls, where: str, d: dict[str, Any]) -> "ScenarioInfo":
        out = cls(**d)
        check_duration(out.duration_s, f"{where}: key 'scenario.duration_s'")
        check_seed(out.seed, f"{where}: key 'scenario.seed'")
        return out


@dataclass(frozen=True)
class BusConfig:
    servos: int = DEFAULT_SERVOS
    first_id: int = DEFAULT_FIRST_ID
    baud: int = DEFAULT_BAUD
    echo: bool = False
    return_delay_us: int | None = None      # None: the servo's own (the control table's)
    edition: str = ax12.EDITION_EMANUAL
    eeprom_busy_us: int | None = None       # None: the model's own (its table's)
    sensor_node: bool | None = None         # None: on with ``hexhil bus --world``
    sensor_node_id: int | None = None
    model: str = models.DEFAULT             # SERVO_MODELS: Protocol 1.0 or 2.0 servos

    @property
    def ids(self) -> range:
        return range(self.first_id, self.first_id + self.servos)

    @classmethod
    def parse(cls, where: str, d: dict[str, Any]) -> "BusConfig":
        b = cls(**d)
        if b.servos < 1 or b.first_id < 0 or b.first_id + b.servos - 1 > 253:
            raise UserError(f"{where}: servos {b.servos} from ID {b.first_id} do not fit "
                            "IDs 0-253")
        if b.baud <= 0:
            raise UserError(f"{where}: key 'bus.baud' must be positive, got {b.baud}")
        if b.model not in SERVO_MODELS:
            raise UserError(f"{where}: key 'bus.model' must be one of "
                            f"{', '.join(SERVO_MODELS)}, got {b.model!r}")
        table = models.table(b.model)
        if table.bps_to_baud(b.baud) < 0:
            raise UserError(f"{where}: baud {b.baud}: {table.BAUD_RULE}")
        max_id = models.codec(b.model).MAX_ID
        if b.first_id + b.servos - 1 > max_id:
            raise UserError(f"{where}: servos {b.servos} from ID {b.first_id} do not fit an "
                            f"{b.model}'s IDs 0-{max_id}")
        if b.sensor_node and models.protocol(b.model) != SENSOR_NODE_PROTOCOL:
            raise UserError(f"{where}: the sensor node speaks Protocol 1.0, not an "
                            f"{b.model}'s Protocol {models.protocol(b.model)}.0")
        if b.edition not in ax12.EDITIONS:
            raise UserError(f"{where}: key 'bus.edition' must be one of "
                            f"{', '.join(ax12.EDITIONS)}, got {b.edition!r}")
        rd = b.return_delay_us
        if rd is not None and (rd % 2 or not 0 <= rd <= RETURN_DELAY_MAX_US):
            raise UserError(f"{where}: key 'bus.return_delay_us' must be even and "
                            f"0-{RETURN_DELAY_MAX_US}, got {rd}")
        node = b.sensor_node_id
        if node is not None and (not 0 <= node <= 253 or node in b.ids):
            raise UserError(f"{where}: key 'bus.sensor_node_id' must be 0-253 and no servo's "
                            f"ID, got {node}")
        if b.eeprom_busy_us is not None and b.eeprom_busy_us < 0:
            raise UserError(f"{where}: key 'bus.eeprom_busy_us' must be 0 or more, "
                            f"got {b.eeprom_busy_us}")
        return b


@dataclass(frozen=True)
class FirmwareConfig:
    """None: the firmware's own default (firmware/config.py)."""

    cycle_hz: float | None = None
    tactile: bool | None = None
    python: Runtime = Runtime.MICROPYTHON
    servo_lost_s: float | None = None
    reads_per_cycle: int | None = None

    @classmethod
    def parse(cls, where: str, d: dict[str, Any]) -> "FirmwareConfig":
        d = dict(d)
        if "python" in d:
            d["python"] = Runtime.parse(d["python"], f"{where}: key 'firmware.python'")
        f = cls(**d)
        _check_keys(where, "firmware", f, {"cycle_hz": (CYCLE_HZ, " Hz", True),
                                           "servo_lost_s": (SERVO_LOST_S, " s", True),
                                           "reads_per_cycle": (READS_PER_CYCLE, "", False)})
        return f


@dataclass(frozen=True)
class GaitConfig:
    """None: the firmware's own default; ``period_s`` defaults to the gait's nominal one."""

    name: str = DEFAULT_GAIT
    period_s: float = 0.0
    step_length_m: float | None = None
    step_height_m: float | None = None
    max_obstacle_height_m: float | None = None
    direction_deg: float | None = None
    distance_m: float | None = None     # the goal ahead, for a navigator

    @classmethod
    def parse(cls, where: str, d: dict[str, Any]) -> "GaitConfig":
        name = d.get("name", DEFAULT_GAIT)
        if name not in GAITS:
            raise UserError(f"{where}: key 'gait.name' must be tripod or wave, got {name!r}")
        g = cls(**{"period_s": hexapod.GAIT_PERIOD_S[name], **d})
        _check_keys(where, "gait", g, {"period_s": (PERIOD_S, " s", False),
                                       "step_length_m": (STEP_LENGTH_M, " m", False),
                                       "step_height_m": (STEP_HEIGHT_M, " m", False),
                                       "max_obstacle_height_m": (OBSTACLE_HEIGHT_M, " m", False),
                                       "direction_deg": (DIRECTION_DEG, " deg", False),
                                       "distance_m": (DISTANCE_M, " m", False)})
        return g


@dataclass(frozen=True)
class FaultsConfig:
    """Rates, and the scheduled faults' tables (checked by hil/servobus/faults.py, their owner)."""

    bit_error_rate: float = 0.0
    drop_status_rate: float = 0.0
    can_drop_rate: float = 0.0
    unplug: tuple[dict[str, Any], ...] = ()
    stall: tuple[dict[str, Any], ...] = ()
    overheat: tuple[dict[str, Any], ...] = ()
    voltage_sag: tuple[dict[str, Any], ...] = ()
    brownout: tuple[dict[str, Any], ...] = ()
    overload: tuple[dict[str, Any], ...] = ()
    position_stuck: tuple[dict[str, Any], ...] = ()
    position_noise: tuple[dict[str, Any], ...] = ()
    id_conflict: tuple[dict[str, Any], ...] = ()
    switch_stuck: tuple[dict[str, Any], ...] = ()
    switch_bounce: tuple[dict[str, Any], ...] = ()
    can_silent: tuple[dict[str, Any], ...] = ()
    can_garbage: tuple[dict[str, Any], ...] = ()
    force_bias: tuple[dict[str, Any], ...] = ()
    force_dropout: tuple[dict[str, Any], ...] = ()

    @classmethod
    def parse(cls, where: str, d: dict[str, Any]) -> "FaultsConfig":
        f = cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in d.items()})
        # bit_error_rate and drop_status_rate: checked by hil/faults.py, their owner
        _check_keys(where, "faults", f, {"can_drop_rate": (RATE, "", False)})
        return f


@dataclass(frozen=True)
class WorldConfig:
    """``kind`` None: no world (kinematic servos); a ``[world]`` without ``kind`` is the
    hexapod. Its other keys (terrain, model, obstacles, ...) are read by hil/world/."""

    kind: WorldKind | None = None

    @classmethod
    def parse(cls, where: str, d: dict[str, Any]) -> "WorldConfig":
        if not d:
            return cls()
        kind = d.get("kind", WorldKind.HEXAPOD.value)
        try:
            return cls(WorldKind(kind))
        except ValueError:
            raise UserError(f"{where}: key 'world.kind' must be one of "
                            f"{', '.join(k.value for k in WorldKind)}, got {kind!r}") from None
