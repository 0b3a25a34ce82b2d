"""What every run has, whoever drives it: the scenario's rig (hil/run/rig.py: clock, servo bus,
faults, world), the run's CAN bus, the host nodes ticked on the clock, the recorder's hooks
(serial bytes, with the run's serial digest; faults) and its ground truth.

Three drivers move the clock: the firmware's link requests (hil/run/lockstep.py ``FirmwareDriver``),
a world that steps itself (``SteppedDriver``), or a foreign master's bytes paced by the
wall clock (hil/run/realtime_rig.py with hil/servobus/serial_server.py). Pacing a lockstep run to the
wall clock is a policy given to the run (``WallClockPacing``), not part of the core.
"""
from __future__ import annotations

import hashlib
import time
from typing import Any, Callable, Protocol, Sequence

from hexhil.hil.run import rig as rig_mod
from hexhil.hil.canbus.bus import CanBus, RecorderListener
from hexhil.hil.run.ground_truth import GroundTruth
from hexhil.hil.scenario import Scenario
from hexhil.hil.seams import CanGateway, FirmwareWorld, HostNode, SteppedWorld, TraceRecorder
from hexhil.hil.servobus import serial_stream
from hexhil.hil.servobus.table_servo import TableServo

OnFault = Callable[[int, str, str], None]


class Pacing(Protocol):
    """When a sample of virtual time ``t_us`` may be handed on (to a recorder, a viewer)."""

    def pace(self, t_us: int) -> None: ...


class Unpaced:
    """As fast as the machine goes: the default, and what every test and sweep runs."""

    def pace(self, t_us: int) -> None:
        return None


class WallClockPacing:
    """Hold each sample until the wall clock has run ``t_us`` since the first one, so a
    person can watch a live view (``hexhil run --realtime``)."""

    def __init__(self) -> None:
        self._wall0_s: float | None = None

    def pace(self, t_us: int) -> None:
        now = time.perf_counter()
        if self._wall0_s is None:
            self._wall0_s = now - t_us * 1e-6
        ahead_s = self._wall0_s + t_us * 1e-6 - now
        if ahead_s > 0:
            time.sleep(ahead_s)


class SerialTap:
    """The servo line's bytes into the run's serial digest and the recorder: a bus's
    ``on_bytes``, which takes the compiled reads' records as one stream too
    (hil/servobus/serial_stream.py)."""

    def __init__(self, recorder: TraceRecorder | None) -> None:
        self.digest = hashlib.sha256()
        self.recorder = recorder

    def __call__(self, t_us: int, direction: str, data: bytes) -> None:
        self.digest.update(serial_stream.head(t_us, direction))
        self.digest.update(data)
        if self.recorder is not None:
            self.recorder.serial(t_us, direction, data)

    def stream(self, stream: bytes, lens: Sequence[int]) -> None:
        self.digest.update(stream)
        if self.recorder is not None:
            self.recorder.serial_stream(stream, lens)


class RunCore:
    """The rig, CAN bus, host nodes, recorder hooks and ground truth of one run.

    ``on_fault`` also hears every injected fault (the recorder always does); the real-time
    rig's CAN bus drops nothing (``can_faults=False``), as it never has."""

    def __init__(self, scenario: dict[str, Any] | Scenario, seed: int = 0, *,
                 world: FirmwareWorld | SteppedWorld | None = None,
                 recorder: TraceRecorder | None = None, can_server: CanGateway | None = None,
                 scene: bool = False, pacing: Pacing | None = None,
                 ids: Sequence[int] | None = None, on_fault: OnFault | None = None,
                 can_faults: bool = True) -> None:
        self.recorder = recorder
        self.pacing: Pacing = pacing if pacing is not None else Unpaced()
        self._also_on_fault = on_fault
        self._serial = SerialTap(recorder)
        self.rig = rig_mod.build(scenario, seed, world=world, ids=ids, on_fault=self._on_fault,
                                 on_bytes=self._serial)
        self.config, self.seed = self.rig.config, seed
        self.world = world
        self.clock, self.bus, self.faults = self.rig.clock, self.rig.bus, self.rig.faults
        self.can = (CanBus(self.clock, self.config.faults.can_drop_rate, seed, self._on_fault)
                    if can_faults else CanBus(self.clock))
        if can_faults:
            self.can.faults = self.faults     # [faults] can_dropped, can_delayed, ...
        if recorder is not None:
            self.can.add(RecorderListener(recorder))
        if can_server is not None:
            self.can.add_gateway(can_server)
        self._nodes: list[HostNode] = []
        self._next_tick_us: list[int] = []
        servos = ([s for s in self.bus.servos if isinstance(s, TableServo)]
                  if self.bus else [])
        self.truth = (GroundTruth(world, servos, recorder, scene, self.bus)
                      if recorder is not None else None)

    @property
    def serial_digest(self) -> str:
        """sha256 over every byte on the servo bus with its time and direction."""
        return self._serial.digest.hexdigest()

    def _on_fault(self, t_us: int, name: str, detail: str) -> None:
        if self.recorder is not None:
            self.recorder.fault(t_us, name, detail)
        if self._also_on_fault is not None:
            self._also_on_fault(t_us, name, detail)

    # --- host nodes ---------------------------------------------------------------------
    def add_node(self, node: HostNode) -> None:
        """A host-side CAN node, ticked in the order added; first after one period, or at
        ``first_tick_us`` if the node has one."""
        self._nodes.append(node)
        self._next_tick_us.append(getattr(node, "first_tick_us", node.period_us))

    def next_tick_us(self) -> int | None:
        """When the next host node is due (None without nodes): the firmware driver stops
        a sleep there, so a node ticks at its period, not at the firmware's next wake."""
        return min(self._next_tick_us) if self._next_tick_us else None

    def tick_nodes(self, t_us: int) -> None:
        """Host nodes whose period has come round, in the order they were given. Ticks
        stay on the node's grid (first tick + n periods): a node at 100 ms from 0 ticks at
        the instants the trace has ground truth for; one a step skipped past is due a
        period after this tick."""
        for i, node in enumerate(self._nodes):
            due = self._next_tick_us[i]
            if t_us >= due:
                due += node.period_us
                self._next_tick_us[i] = due if due > t_us else t_us + node.period_us
                node.tick(t_us)

    def inject(self, kind: str, **params: Any) -> dict[str, Any]:
        """A named fault (hil/servobus/faults.py ``KINDS``) as a ``[faults]`` entry, now or
        at ``at_s`` of run time: from the API or a host node; it goes to /faults and the
        summary's counts like a scenario's."""
        faults = self.faults
        if self.bus is not None and self.bus.faults is None:
            self.bus.faults = faults          # a run without faults gets its first now
            faults.attach(self.bus, t0_us=0)
        return faults.inject(kind, **params)

    def send_can(self, arb_id: int, data: bytes) -> None:
        """Put a frame on the run's CAN bus from the host."""
        self.can.send(arb_id, data)

    def switch_bits(self) -> int:
        """The world's six limit switches as bits (bit i = leg i pressed), 0 without one,
        as the firmware reads them: stuck, bouncing or swing-pressed legs applied
        (``[faults]``)."""
        bits = 0
        if self.world is not None:
            levels = self.world.switch_levels()
            if True in levels:   # most link requests: none pressed
                for i, pressed in enumerate(levels):
                    if pressed:
                        bits |= 1 << i
        if not self.faults:
            return bits
        return self.faults.switch_bits(self.clock.t_us, bits, self.world.foot_contacts
                                       if self.world is not None else None)

    def shutdown(self) -> None:
        self.can.shutdown()
