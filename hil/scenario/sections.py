"""A scenario's sections as typed, frozen objects: each section's defaults and rules beside
its type, applied once when a scenario is loaded (hil/scenario/__init__.py).

Keys a section leaves to the firmware (``firmware/config.py``: cycle rate, tactile rule,
servo loss time) stay None here when the file does not set them: their defaults live with
their owner, on the other floor. The world's and the faults' sections are world.py and
faults.py; range rules come from rules.py. Every number a scenario, a flag or an argument
takes has a stated range (docs/api.md): the ranges below, ``check_duration``, ``check_seed``
and ``check_span`` are the CLI's and the API's checks too.
"""
from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Any

from hexhil.hil.scenario.rules import at_least, positive, within
from hexhil.protocol import hexapod
from hexhil.protocol.dynamixel import ax12, models
from hexhil.protocol.errors import BadValue

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
SEED_MAX = 2**32 - 1             # the RNGs' seed (numpy SeedSequence, MuJoCo terrain): 32 bits
# (low, high, low excluded) of the gait's and the firmware's numbers:
GAIT_RANGES = {
    "period_s": (0.1, 60.0, False),        # a gait cycle: at least 5 of the firmware's 20 ms
    "step_length_m": (0.0, 0.2, False),    # the leg's reach (coxa 5 + femur 8.2 + tibia 12 cm)
    "step_height_m": (0.0, 0.15, False),
    "max_obstacle_height_m": (0.0, 0.15, False),
    "direction_deg": (-360.0, 360.0, False),
    "distance_m": (0.0, 1000.0, False),    # a goal ahead (0: none; the experiments' probe)
}
FIRMWARE_RANGES = {
    "cycle_hz": (0.0, 1000.0, True),       # the firmware's control rate
    "servo_lost_s": (0.0, 3600.0, True),
    "reads_per_cycle": (0, 254, False),
}


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
            raise BadValue(f"{what} must be one of {', '.join(r.value for r in cls)}, "
                           f"got {value!r}") from None


def check_duration(value: float, what: str, params: tuple[str, ...] = ()) -> float:
    """A run's length in seconds: positive, finite and within ``MAX_DURATION_S``; ``params``:
    the API parameter ``what`` names (protocol/errors.py)."""
    positive(what, value, params)
    if not value <= MAX_DURATION_S:
        raise BadValue(f"{what} must be at most {MAX_DURATION_S:g} s (a trace's clock is "
                       f"u64 nanoseconds), got {value}", params=params)
    return float(value)


def check_seed(value: int, what: str, params: tuple[str, ...] = ()) -> int:
    """A seed: an integer from 0 to ``SEED_MAX`` (the RNGs take 32 bits)."""
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= SEED_MAX:
        raise BadValue(f"{what} must be an integer from 0 to {SEED_MAX} (2**32 - 1), "
                       f"got {value!r}", params=params)
    return value


def check_span(start_s: float | None, end_s: float | None) -> None:
    """A stretch of a trace (``start_s``/``end_s``, seconds from its start; None: open):
    finite, within a trace's clock, and not empty."""
    for value, what in ((start_s, "start_s"), (end_s, "end_s")):
        if value is not None:
            within(what, value, 0.0, MAX_DURATION_S, params=(what,))
    if start_s is not None and end_s is not None and not start_s < end_s:
        raise BadValue(f"start_s {start_s:g} s is not before end_s {end_s:g} s: the range "
                       "is empty", params=("start_s", "end_s"))


def _check_ranges(where: str, section: str, values: Any,
                  ranges: dict[str, tuple[float, float, bool]]) -> None:
    """Each key of ``ranges`` that ``values`` sets (not None) within its range."""
    for key, (low, high, low_open) in ranges.items():
        v = getattr(values, key)
        if v is not None:
            within(f"{where}: key '{section}.{key}'", v, low, high, low_open=low_open)


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
            raise BadValue(f"{where}: servos {b.servos} from ID {b.first_id} do not fit "
                           "IDs 0-253")
        positive(f"{where}: key 'bus.baud'", b.baud)
        if b.model not in SERVO_MODELS:
            raise BadValue(f"{where}: key 'bus.model' must be one of "
                           f"{', '.join(SERVO_MODELS)}, got {b.model!r}")
        table = models.table(b.model)
        if table.bps_to_baud(b.baud) < 0:
            raise BadValue(f"{where}: baud {b.baud}: {table.BAUD_RULE}")
        max_id = models.codec(b.model).MAX_ID
        if b.first_id + b.servos - 1 > max_id:
            raise BadValue(f"{where}: servos {b.servos} from ID {b.first_id} do not fit an "
                           f"{b.model}'s IDs 0-{max_id}")
        if b.sensor_node and models.protocol(b.model) != SENSOR_NODE_PROTOCOL:
            raise BadValue(f"{where}: the sensor node speaks Protocol 1.0, not an "
                           f"{b.model}'s Protocol {models.protocol(b.model)}.0")
        if b.edition not in ax12.EDITIONS:
            raise BadValue(f"{where}: key 'bus.edition' must be one of "
                           f"{', '.join(ax12.EDITIONS)}, got {b.edition!r}")
        rd = b.return_delay_us
        if rd is not None and (rd % 2 or not 0 <= rd <= RETURN_DELAY_MAX_US):
            raise BadValue(f"{where}: key 'bus.return_delay_us' must be even and "
                           f"0-{RETURN_DELAY_MAX_US}, got {rd}")
        node = b.sensor_node_id
        if node is not None and (not 0 <= node <= 253 or node in b.ids):
            raise BadValue(f"{where}: key 'bus.sensor_node_id' must be 0-253 and no servo's "
                           f"ID, got {node}")
        if b.eeprom_busy_us is not None:
            at_least(f"{where}: key 'bus.eeprom_busy_us'", b.eeprom_busy_us, 0)
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
        _check_ranges(where, "firmware", f, FIRMWARE_RANGES)
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
            raise BadValue(f"{where}: key 'gait.name' must be tripod or wave, got {name!r}")
        g = cls(**{"period_s": hexapod.GAIT_PERIOD_S[name], **d})
        _check_ranges(where, "gait", g, GAIT_RANGES)
        return g
