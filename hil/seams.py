"""The run's seams, declared: what a world, a servo's actuator, a host node, a CAN gateway, a
recorder and the link's host side must offer (hil/run/core.py, hil/run/lockstep.py,
hil/link/). Anything with these methods plugs in; nothing needs to inherit from them."""
from __future__ import annotations

from typing import (TYPE_CHECKING, Any, Callable, Iterator, Mapping, Protocol, Sequence,
                    TypeVar, runtime_checkable)

if TYPE_CHECKING:
    import can

    from hexhil.hil.clock import VirtualClock
    from hexhil.hil.run_result import BeamsOutcome, RunTally


@runtime_checkable
class HostNode(Protocol):
    """A host-side node on the run's CAN bus (a planner, a logger, a fault), ticked on the
    run's virtual clock every ``period_us``: first after one period, or at ``first_tick_us``
    when the node has that attribute (optional, so not declared here). It reaches the bus
    through an endpoint the run gives it (``Run.can_endpoint``)."""

    period_us: int

    def tick(self, t_us: int) -> None: ...


class Actuator(Protocol):
    """What a servo drives: kinematic in hil/servobus, a physics joint in the hexapod world."""

    def command(self, goal_rad: float, speed_limit_rad_s: float, torque_limit_frac: float,
                enabled: bool, compliance: tuple[int, int, int, int, int]) -> None:
        """New set-point; compliance = (cw_margin, ccw_margin, cw_slope, ccw_slope, punch), raw.

        ``goal_rad`` is +inf (CCW) or -inf (CW) in wheel mode: turn endlessly at the speed.
        """

    def state(self) -> tuple[float, float, float]:
        """(position_rad, velocity_rad_s, load_frac); CCW positive, load in [-1, 1]."""

    def advance_to(self, t_us: int) -> None:
        """Move to virtual time t_us (kinematic model only; physics steps itself)."""


class CanPort(Protocol):
    """A node's port on the run's CAN bus (hil/canbus/bus.py ``Endpoint``)."""

    def send(self, msg: "can.Message") -> None: ...
    def frames(self, limit: int = -1) -> Iterator["can.Message"]: ...


class CanHub(Protocol):
    """The run's CAN bus as a node attaches to it (hil/canbus/bus.py ``CanBus``)."""

    def endpoint(self, direction: str) -> CanPort: ...


class CanGateway(Protocol):
    """A way in and out of the run's CAN bus for programs outside it (hil/canbus/socketcand.py
    ``CanServer``): it hears every frame, and ``poll`` hands over what came in since."""

    def on_message_received(self, msg: "can.Message") -> None: ...
    def poll(self) -> list[tuple[int, bytes, bool]]: ...      # (arbitration id, data, extended)


class LineDevice(Protocol):
    """A device on a servo line (an emulated servo, the switch node) as the run's checks
    see it: its ID and the rate its UART listens at."""

    @property
    def id(self) -> int: ...
    @property
    def baud_bps(self) -> int: ...


class ServoLine(Protocol):
    """A simulated servo line (hil/servobus/line.py ``Bus``, ``Bus2``) as its master's side
    sees it: bytes written and read in virtual time, and the timing hooks a timing-margin
    run turns."""

    return_delay_override_us: int | None
    rx_latency_us: int
    baud: int
    servos: Sequence[LineDevice]
    stats: Mapping[str, int]       # tx_bytes, rx_bytes, packets, replies, ...
    missing_ids: set[int]          # IDs packets went to that no device has

    def set_master_baud(self, baud: int) -> None: ...
    def master_write(self, data: bytes) -> None: ...
    def master_read(self, n: int, timeout_us: int) -> bytes: ...
    def master_discard(self) -> int: ...
    def next_bytes(self) -> tuple[int | None, int]: ...
    def idle_until(self, t_us: int) -> None: ...
    def wire_us(self, nbytes: int) -> int: ...


class LinkHost(Protocol):
    """The host side of one firmware link (hil/link/server.py ``LinkServer``), as the served
    firmware and the board line use it: the bus's clock, the run's faults and events, the
    board's sleeps, and ``serve`` for a connection."""

    clock: "VirtualClock"
    bus: ServoLine
    byte_us: float                         # one byte's wire time at the master's rate
    console: Callable[[], None] | None     # takes what the firmware printed, as it sleeps
    watch: Any                             # the run's limits (hil/run/limits.py), or None

    def serve(self, conn: Any, end_us: int, result: "RunTally") -> None: ...
    def answer(self, conn: Any, msgs: list[tuple[int, bytes]], closed: bool, end_us: int,
               result: "RunTally") -> bool: ...
    def take_event(self, kind: int, text: str, result: "RunTally") -> None: ...
    def run_fault(self, name: str, detail: str, result: "RunTally") -> None: ...
    def idle_to(self, wake_us: int) -> None: ...
    def on_wake(self, t_us: int) -> None: ...
    def on_slept(self) -> None: ...


class Pose(Protocol):
    x_m: float
    y_m: float
    z_m: float
    yaw_rad: float
    quat_wxyz: Sequence[float]


class FirmwareWorld(Protocol):
    """A world the firmware drives through the servo bus (the MuJoCo hexapod): one actuator
    per servo, in servo-ID order, advanced by the bus's clock."""

    def actuators(self) -> Sequence[Actuator]: ...
    def advance_to(self, t_us: int) -> None: ...
    def switch_levels(self) -> Sequence[bool]: ...   # the six limit switches, LF..RH
    def foot_contacts(self) -> Sequence[bool]: ...   # which feet carry load, LF..RH
    def body_pose(self) -> Pose: ...
    def joint_names(self) -> Sequence[str]: ...
    def joint_positions(self) -> Any: ...              # numpy arrays, joint order
    def joint_velocities(self) -> Any: ...
    def joint_efforts_nm(self) -> Any: ...


class CheckpointWorld(Protocol):
    """A FirmwareWorld that can run ahead of the run's clock and be put back (the lookahead,
    hil/run/lookahead.py): ``checkpoint()`` is None where it cannot."""

    t_us: int

    def advance_to(self, t_us: int) -> None: ...
    def next_step_us(self) -> int: ...
    def checkpoint(self) -> Any: ...
    def restore(self, saved: Any) -> None: ...


class SteppedWorld(Protocol):
    """A world that steps itself and speaks CAN (seed 000's beams, hil/world/beams_node.py)."""

    @property
    def t_us(self) -> int: ...
    def attach(self, can: CanHub) -> None: ...
    def step(self) -> None: ...
    def done(self) -> bool: ...
    def outcome(self) -> "BeamsOutcome": ...


T = TypeVar("T")


class HeldSample(Sequence[T]):
    """A sample held as the raw values it follows from (``args``): its items are made by
    ``_make(*args)`` when first read, and it pickles as ``args`` alone. The recorder holds
    one as it is, and reads it where it encodes (hil/world/scene_values.py
    ``JointFrames``, ``ContactForces``; hil/servobus/servo_core.py ``StateRows``)."""

    def __init__(self, *args: Any) -> None:
        self.args = args
        self._items: list[T] | None = None

    def __reduce__(self) -> tuple:
        return type(self), self.args

    def __len__(self) -> int:
        return len(self.items())

    def __getitem__(self, i: Any) -> Any:
        return self.items()[i]

    def __iter__(self) -> Iterator[T]:
        return iter(self.items())

    def items(self) -> list[T]:
        if self._items is None:
            self._items = self._make(*self.args)
        return self._items

    @staticmethod
    def _make(*args: Any) -> list[T]:
        raise NotImplementedError


# A servo's state as the recorder takes it (``TraceRecorder.servo_state``): a mapping of
# these keys, or a tuple of them in this order (hil/servobus/table_servo.py ``state_row``).
SERVO_STATE_FIELDS = ("id", "position_rad", "velocity_rad_s", "load_frac", "temperature_c",
                      "voltage_v", "torque_enabled", "moving", "error")


class TraceRecorder(Protocol):
    """Where a run writes what happened (host_tools/trace/recorder.py ``Recorder``), in
    virtual microseconds; ``advance`` says no earlier message will come."""

    def advance(self, t_us: int) -> None: ...
    def work_while(self, waiting: Callable[[], bool]) -> None: ...
    def serial(self, t_us: int, direction: str, data: bytes) -> None: ...
    def serial_stream(self, stream: bytes, lens: Sequence[int]) -> None: ...
    def can(self, t_us: int, arb_id: int, data: bytes, direction: str = "tx",
            is_extended_id: bool = False) -> None: ...
    def link(self, t_us: int, request: bytes, reply: bytes, kind: str = "") -> None: ...
    def switch_edge(self, t_us: int, leg: int, level: bool) -> None: ...
    def telemetry(self, t_us: int, values: Mapping[str, Any]) -> None: ...
    def fault(self, t_us: int, name: str, detail: str = "") -> None: ...
    def violation(self, t_us: int, kind: str, detail: str) -> None: ...
    def servo_state(self, t_us: int, servos: Any) -> None: ...
    def body_pose(self, t_us: int, position_m: Sequence[float],
                  quaternion_wxyz: Sequence[float]) -> None: ...
    def joints(self, t_us: int, names: Sequence[str], positions_rad: Sequence[float],
               velocities_rad_s: Sequence[float] | None = None,
               efforts_nm: Sequence[float] | None = None) -> None: ...
    def scene(self, t_us: int, shapes: Sequence[Any]) -> None: ...
    def scene_frames(self, t_us: int, frames: Sequence[Any]) -> None: ...
    def scene_forces(self, t_us: int, arrows: Sequence[Any]) -> None: ...
    def close(self) -> None: ...
