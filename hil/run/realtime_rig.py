"""The real-time rig of ``hexhil bus``: the scenario's servos (and world) for any firmware.

Around the rig of hil/run/rig.py it adds what a foreign master needs and what ``hexhil run``
records: the limit-switch sensor node on the bus (hil/servobus/switch_node.py), the master
conformance check (hil/servobus/master_check.py), the switches as CAN frames (``limit_switches``) on
the run's CAN bus and its socketcand gateway, and the recorder's topics (serial, CAN,
``/body``, ``/joints``, the 3D scene (hil/run/ground_truth.py, as ``hexhil run --out``),
``/servos``, ``/switches``, ``/faults``, ``/bus/violations``).
hil/servobus/serial_server.py paces it to the wall clock and calls ``tick`` after each catch-up.
"""
from __future__ import annotations

from typing import Any, Callable, Sequence

from hexhil.hil.run import rig as rig_mod
from hexhil.hil import scenario as scenario_mod
from hexhil.hil.servobus.master_check import MasterCheck
from hexhil.hil.run.core import RunCore
from hexhil.hil.scenario import Scenario
from hexhil.hil.seams import CanGateway, TraceRecorder
from hexhil.hil.run_result import BodyDisplacement
from hexhil.hil.servobus.switch_node import DEFAULT_ID, SensorNode
from hexhil.protocol import can_frames as cf
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.errors import BadValue, UserError

SAMPLE_US = 100_000        # ground truth, servo states and the CAN switches frame: 10 Hz


class RealTimeRig:
    """Builds the rig with its extras; ``tick(t_us)`` samples, ``summary()`` reports."""

    def __init__(self, scenario: Scenario | dict[str, Any], seed: int, *, world: bool = False,
                 ids: Sequence[int] | None = None, recorder: TraceRecorder | None = None,
                 can_server: CanGateway | None = None, sensor_id: int | None = DEFAULT_ID,
                 verbose: Callable[[str], None] | None = None, scene: bool = True) -> None:
        self.recorder, self.verbose = recorder, verbose
        sc = scenario_mod.parse(scenario)
        w = rig_mod.make_world(sc, seed) if world else None
        if world and w is None:
            raise UserError(f"{sc.path}: world needs a scenario with a [world] section",
                            params=("world",))
        # the run core: rig, CAN bus, recorder hooks and ground truth, as hexhil run's
        self.core = RunCore(sc, seed, world=w, recorder=recorder, can_server=can_server,
                            scene=scene, ids=ids, on_fault=self._verbose_fault,
                            can_faults=False)
        self.rig = self.core.rig
        if self.rig.bus is None:
            raise UserError(f"{sc.path}: the {sc.world.kind.value} world has no servo bus")
        self.world, self.bus, self.clock, self.can = w, self.rig.bus, self.rig.clock, self.core.can
        self.servos = list(self.bus.servos)
        self.check = MasterCheck(self._on_violation, self.bus.protocol)
        self.bus.monitor = self.check
        self.node = None
        if sensor_id is not None:
            if self.bus.servo(sensor_id) is not None:
                raise BadValue(f"sensor node ID {sensor_id} is already a servo's")
            self.node = SensorNode(self.core.switch_bits, sensor_id,
                                   ax12.bps_to_baud(self.bus.baud))
            self.bus.add_device(self.node)
        self._pose0 = w.body_pose() if w is not None else None
        self._bits = 0
        self._edges = 0
        self._seq = 0
        self._next_sample_us = 0

    def _verbose_fault(self, t_us: int, name: str, detail: str) -> None:
        if self.verbose is not None:
            self.verbose(f"fault t={t_us / 1e6:.6f}s {name}: {detail}")

    def _on_violation(self, t_us: int, kind: str, detail: str) -> None:
        if self.recorder is not None:
            self.recorder.violation(t_us, kind, detail)
        if self.verbose is not None:
            self.verbose(f"master t={t_us / 1e6:.6f}s {kind}: {detail}")

    def _send_switches(self, bits: int) -> None:
        frame = cf.encode("limit_switches", switches=bits, sequence=self._seq)
        if self.core.faults is not None:
            frame = self.core.faults.can_frame(*frame)   # [faults] can_silent, can_garbage
        if frame is not None:
            self.can.send(*frame)
        self._seq = (self._seq + 1) & 0xFF

    def tick(self, t_us: int) -> None:
        """After each catch-up: switch edges (recorder, CAN), 10 Hz samples, CAN in."""
        bits = self.core.switch_bits()
        changed = bits ^ self._bits
        if changed:
            self._bits = bits
            for i in range(6):
                if changed & (1 << i):
                    self._edges += 1
                    if self.recorder is not None:
                        self.recorder.switch_edge(t_us, i, bool(bits & (1 << i)))
            self._send_switches(bits)
        self.can.poll()
        if t_us < self._next_sample_us:
            return
        self._next_sample_us = t_us - t_us % SAMPLE_US + SAMPLE_US
        self._send_switches(bits)
        rec = self.recorder
        if rec is None:
            return
        rec.advance(t_us)
        if self.world is not None:
            self.core.truth.world_sample(t_us)
        self.core.truth.servo_sample(t_us)

    def summary(self, pacing: dict[str, Any]) -> dict[str, Any]:
        """The ``--json`` summary: time served, body, faults, bus, master violations, pacing."""
        st = self.bus.stats
        out: dict[str, Any] = {
            "scenario": self.rig.config.path, "seed": self.rig.seed,
            "served_s": round(self.clock.t_us * 1e-6, 6),
            "bus": dict(st), "faults": dict(self.rig.faults.counts),
            "switch_edges": self._edges, "violations": self.check.summary(), "pacing": pacing,
            "sensor_node": None if self.node is None else
            {"id": self.node.id, "instructions": self.node.instructions}}
        if self.world is not None:
            out["body"] = {k: round(v, 6) for k, v in
                           BodyDisplacement.between(self._pose0, self.world.body_pose()).as_dict().items()}
            out["world_s"] = self.world.t_us * 1e-6
        return out

    def close(self) -> None:
        self.core.shutdown()
