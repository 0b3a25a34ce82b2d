"""The run's CAN bus: one python-can bus per run, fanned out to ``can.Listener``s in lockstep.

Every participant is a python-can ``Listener``: the firmware's inbox, seed 000's world and
host nodes (``Endpoint``, a ``can.BufferedReader`` that can also send), the recorder
(``RecorderListener``) and the socketcand server (``hil.canbus.socketcand.CanServer``, a gateway:
its clients' frames come in through ``poll()``). A frame sent
by one is delivered to every other at the same virtual time, and is also put on the run's
python-can ``virtual`` bus (``channel``), so in-process python-can code can join the run;
``poll()`` brings what such code sends back in.

python-can's ``Notifier`` is not used: it dispatches on a thread per bus, so when a frame
reached a listener would depend on the wall clock and a seed would no longer give the same
trace. Dispatch here is synchronous, in the order listeners were added.

Frame loss (the scenario's ``faults.can_drop_rate``): each frame is lost with that
probability before anyone sees it, drawn from an RNG seeded by the run's seed (and drawn
only when the rate is set, so runs without it are unchanged); every loss is reported
through ``on_fault`` ("can_drop") and counted in ``dropped``.
"""
from __future__ import annotations

import itertools
import random
from typing import Any, Callable, Iterator

import can

from hexhil.hil.clock import VirtualClock
from hexhil.hil.seams import CanGateway, TraceRecorder
from hexhil.protocol import can_frames
from hexhil.protocol.errors import BadValue

_channels = itertools.count()


def message(name: str, **signals: float) -> can.Message:
    """Our DBC's frame ``name`` (protocol/can_frames.py) as a python-can message."""
    arb_id, data = can_frames.encode(name, **signals)
    return can.Message(arbitration_id=arb_id, data=data, is_extended_id=False)


def standard_frame(msg: can.Message) -> tuple[int, bytes]:
    """(arbitration id, data) of a standard 11-bit data frame, the only kind a run carries."""
    if msg.is_extended_id or msg.is_remote_frame or msg.is_error_frame or msg.is_fd:
        raise BadValue("a run's CAN bus carries standard 11-bit data frames: "
                       f"got {msg!r}")
    if not 0 <= msg.arbitration_id <= 0x7FF:
        raise BadValue(f"arbitration id 0x{msg.arbitration_id:X} is not an 11-bit id")
    return msg.arbitration_id, bytes(msg.data)


def t_us_of(msg: can.Message) -> int:
    """A frame's virtual time (its timestamp is virtual seconds)."""
    return round(msg.timestamp * 1e6)


class Endpoint(can.BufferedReader):
    """A node on the bus: frames the others send queue here until the node reads them.

    ``direction`` is how the recorder logs what this node sends, relative to the robot's
    controller (``tx``: the controller's side sent it; ``rx``: it is for the controller).
    """

    def __init__(self, bus: "CanBus", direction: str, hears: str | None = None) -> None:
        """``hears``: only frames sent in that direction (``tx``: the controller's), else
        every frame but its own."""
        super().__init__()
        self._bus, self.direction, self.hears = bus, direction, hears

    def on_message_received(self, msg: can.Message) -> None:
        if self.hears is None or (msg.is_rx == (self.hears == "rx")):
            super().on_message_received(msg)

    def send(self, msg: can.Message) -> None:
        """``msg`` on the run's bus now, as python-can's ``BusABC.send`` takes it (its
        timestamp is the run's virtual time, not the message's)."""
        self.send_frame(*standard_frame(msg))

    def send_frame(self, arb_id: int, data: bytes) -> None:
        """A standard frame's id and bytes, already checked: the link's host side, which
        has them as the firmware sent them, builds the message once, here."""
        self._bus.send(arb_id, data, sender=self, direction=self.direction)

    def frames(self, limit: int = -1) -> Iterator[can.Message]:
        """The queued frames, oldest first (at most ``limit``; all if negative)."""
        while limit and not self.buffer.empty():   # BufferedReader's queue: no Empty raised
            msg = self.get_message(0)
            if msg is None:
                return
            limit -= 1
            yield msg


class RecorderListener(can.Listener):
    """Every frame to the recorder's ``/can`` topics, with its sender's direction."""

    def __init__(self, recorder: TraceRecorder) -> None:
        self.recorder = recorder

    def on_message_received(self, msg: can.Message) -> None:
        self.recorder.can(t_us_of(msg), msg.arbitration_id, bytes(msg.data),
                          "rx" if msg.is_rx else "tx")


class CanBus:
    """The fan-out; ``send`` stamps each frame with the clock's virtual time."""

    def __init__(self, clock: VirtualClock, drop_rate: float = 0.0, seed: int = 0,
                 on_fault: Callable[[int, str, str], None] | None = None) -> None:
        self.clock = clock
        self.drop_rate = drop_rate
        self.dropped = 0
        self._drop_rng = random.Random(f"{seed}:can")
        self._on_fault = on_fault
        self.channel = f"hexhil-run-{next(_channels)}"
        self.bus = can.Bus(interface="virtual", channel=self.channel,
                           receive_own_messages=False, preserve_timestamps=True)
        self.listeners: list[can.Listener] = []
        self.gateways: list[CanGateway] = []
        self.faults: Any = None    # hil/servobus/faults.py: its CAN faults mangle frames
        self._held: list[tuple[int, int, bytes, Any, str]] = []   # (release, id, data, ...)

    def add_gateway(self, gateway: CanGateway) -> None:
        """A listener that also brings frames in from outside (``poll() -> [(id, data,
        extended)]``), e.g. the socketcand server's clients."""
        self.add(gateway)
        self.gateways.append(gateway)

    def add(self, listener: can.Listener) -> can.Listener:
        self.listeners.append(listener)
        return listener

    def endpoint(self, direction: str, hears: str | None = None) -> Endpoint:
        return self.add(Endpoint(self, direction, hears))

    def send(self, arb_id: int, data: bytes, sender: Any = None, direction: str = "rx") -> None:
        """One standard (11-bit) frame, the only kind our DBC defines."""
        if self.drop_rate and self._drop_rng.random() < self.drop_rate:
            self.dropped += 1
            if self._on_fault is not None:
                self._on_fault(self.clock.t_us, "can_drop", f"frame 0x{arb_id:03X} lost")
            return
        faults = self.faults
        if faults is not None and (faults.can_faults or self._held):
            self._mangled(arb_id, data, sender, direction)
            return
        self._put(arb_id, data, sender, direction)

    def _put(self, arb_id: int, data: bytes, sender: Any, direction: str) -> None:
        msg = can.Message(timestamp=self.clock.t_us * 1e-6, arbitration_id=arb_id,
                          is_extended_id=False, data=data, is_rx=direction == "rx")
        self.bus.send(msg)
        self._deliver(msg, sender)

    def _mangled(self, arb_id: int, data: bytes, sender: Any, direction: str) -> None:
        """A frame through the CAN faults active now: lost, garbled, held back a while
        (``release_due`` delivers it) or held until the next frame has gone (swapped)."""
        verdict, delay_us, data = self.faults.can_mangle(data)
        swapped = [h for h in self._held if h[0] < 0]
        self._held = [h for h in self._held if h[0] >= 0]
        if verdict == "hold" and (delay_us >= 0 or not swapped):
            release = -1 if delay_us < 0 else self.clock.t_us + delay_us
            self._held.append((release, arb_id, data, sender, direction))
        elif verdict != "drop":       # sent, or the frame a held one is swapped with
            self._put(arb_id, data, sender, direction)
        for _, *frame in swapped:
            self._put(*frame)

    def release_due(self) -> None:
        """Deliver the delayed frames due by now, in the order they were sent."""
        now = self.clock.t_us
        due = [h for h in self._held if 0 <= h[0] <= now]
        if due:
            self._held = [h for h in self._held if not 0 <= h[0] <= now]
            for _, *frame in due:
                self._put(*frame)

    def _deliver(self, msg: can.Message, sender: Any) -> None:
        for listener in self.listeners:
            if listener is not sender:
                listener.on_message_received(msg)

    def poll(self) -> None:
        """Deliver what came in from outside since the last call (logged as ``rx``): the
        gateways' frames, then what in-process python-can code sent on ``channel``."""
        if self._held:
            self.release_due()
        for gateway in self.gateways:
            for arb_id, data, extended in gateway.poll():
                if not extended:
                    self.send(arb_id, data, sender=gateway)
        # python-can 4.6.1's VirtualBus: what others sent it, in a Queue whose deque is read
        # here without its lock (an empty recv(timeout=0) costs 10 us a cycle, empty() 0.5)
        waiting = self.bus.queue.queue
        while waiting:
            msg = self.bus.recv(timeout=0)
            if msg is None:
                return
            msg.timestamp, msg.is_rx = self.clock.t_us * 1e-6, True
            self._deliver(msg, None)

    def shutdown(self) -> None:
        self.bus.shutdown()
