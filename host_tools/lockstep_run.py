"""One run of a scenario, built in one place: ``hexhil run``, the tactile-hexapod experiment,
the GRNN dataset, the bench and the public API (docs/api.md) all run the robot through ``Run``.

A ``Run`` takes a scenario (a ``Scenario``, or a file), picks the firmware runtime, opens
the trace (with the scenario's own data in its metadata, so a trace can be read back
without the file), builds the world and the lockstep simulator (hil/run/lockstep.py), and takes
host nodes (hil/seams.py ``HostNode``) before ``run()`` returns the typed ``RunResult``.
A beams scenario (seed 000) runs its own host nodes, plugged in by its paper's package
(host_tools/plugins.py).
"""
from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hexhil.hil import scenario as scenario_mod
from hexhil.hil.canbus.bus import CanBus, Endpoint, standard_frame
from hexhil.hil.run.limits import MASKED_LIMIT_S, RunLimits
from hexhil.hil.run.rig import make_world
from hexhil.hil.run_result import RunInterrupted, RunResult
from hexhil.hil.scenario import Runtime, Scenario, WorldKind
from hexhil.hil.seams import CanGateway, HostNode, TraceRecorder
from hexhil.hil.servobus.master_check import MasterCheck
from hexhil.hil.link.served_firmware import ElfFirmware, served_firmware
from hexhil.hil.mcu.flash_fs import FlashFiles
from hexhil.hil.run.lockstep import Simulator
from hexhil import plugins
from hexhil.lifecycle import Closing
from hexhil.protocol import link_schema as ls
from hexhil.protocol.dynamixel import models
from hexhil.protocol.errors import UserError
from hexhil.trace.run_metadata import trace_metadata

if TYPE_CHECKING:
    from hexhil.trace.windows import EncodeIn

NO_RUNTIME = "none"   # a beams run has no firmware


class Run(Closing):
    """One run of ``scenario`` (a ``Scenario``, a file, or a dict as TOML reads it); ``seed``, ``runtime`` and ``duration_s`` default to the
    scenario's. ``trace`` records it to MCAP; with ``live_port`` its channels are also served
    over the Foxglove WebSocket protocol on 127.0.0.1 (``live``, host_tools/trace/live.py;
    0 picks a free port; started once the world is built, so a viewer misses nothing); ``can_server`` bridges the CAN bus to socketcand
    clients; ``realtime`` paces virtual time to the wall clock; ``tactile`` overrides the
    scenario's ``firmware.tactile``; ``firmware``, a MicroPython main file run on the virtual
    board (docs/your-firmware.md) or an executable that speaks the link (a C firmware,
    docs/c-firmware.md) or an STM32F411 ELF (docs/elf-firmware.md: ``gdb_port``, ``coverage``,
    ``masked_limit_s`` for its masked-spin and fault-handler verdicts;
    ``flash_files``, MicroPython's ``/flash``: docs/micropython-on-the-chip.md),
    runs instead of ours. An existing ``trace`` file is refused unless ``overwrite``
    (host_tools/trace/target.py). Every argument given is an override, recorded in the
    trace's metadata with the scenario as run (``overrides`` adds what else the caller
    changed, e.g. margin's bus timing); ``what_ran()`` says the same for the summary.
    ``limits`` (hil/run/limits.py ``RunLimits``: a wall-clock and a memory cap, sane by
    default) end a run that hits one with ``Ending.LIMIT``. Close it (or use ``with``) if
    ``run`` is never called."""

    def __init__(self, scenario: Scenario | dict[str, Any] | str | Path, *,
                 seed: int | None = None,
                 runtime: Runtime | str | None = None, duration_s: float | None = None,
                 tactile: bool | None = None, trace: str | Path | None = None,
                 live_port: int | None = None, can_server: CanGateway | None = None,
                 realtime: bool = False, firmware: str | Path | None = None,
                 gdb_port: int | None = None, coverage: str | Path | None = None,
                 flash_files: FlashFiles | None = None, coverage_libraries: bool = False,
                 overwrite: bool = False, overrides: dict[str, Any] | None = None,
                 limits: RunLimits | None = None, masked_limit_s: float | None = None) -> None:
        # a firmware of the user's (hil/link/served_firmware.py) is checked before anything opens
        self.firmware = (served_firmware(firmware, gdb_port=gdb_port, coverage=coverage,
                                         flash_files=flash_files,
                                         coverage_libraries=coverage_libraries,
                                         masked_limit_s=(MASKED_LIMIT_S if masked_limit_s is None
                                                         else masked_limit_s))
                         if firmware is not None else None)
        if masked_limit_s is not None and not isinstance(self.firmware, ElfFirmware):
            raise UserError("masked_limit_s needs an STM32F411 ELF given as firmware",
                            params=("masked_limit_s", "firmware"))
        if firmware is None and flash_files is not None:
            raise UserError("main, fs and fs_out need a MicroPython STM32F411 ELF given as "
                            "firmware", params=("main", "fs", "fs_out", "firmware"))
        if firmware is None and (gdb_port is not None or coverage is not None):
            raise UserError("gdb_port and coverage need an STM32F411 ELF given as firmware",
                            params=("gdb_port", "coverage", "firmware"))
        if coverage_libraries and coverage is None:
            raise UserError("coverage_libraries needs coverage (the LCOV file to write)",
                            params=("coverage_libraries", "coverage"))
        self.scenario = (scenario_mod.load_scenario(scenario)
                         if isinstance(scenario, (str, Path)) else scenario_mod.parse(scenario))
        sc = self.scenario
        self.seed = sc.scenario.seed if seed is None else scenario_mod.check_seed(
            seed, "seed", params=("seed",))
        if tactile is not None and self.firmware is not None:
            raise UserError("tactile sets our firmware's obstacle rule: a firmware of yours "
                            f"({firmware}) reads no such setting", params=("tactile",))
        self.runtime = (sc.firmware.python if runtime is None
                        else Runtime.parse(runtime, "runtime") if isinstance(runtime, str)
                        else runtime)
        self.duration_s = (sc.scenario.duration_s if duration_s is None
                           else scenario_mod.check_duration(duration_s, "duration_s"))
        self.beams = sc.world.kind is WorldKind.BEAMS
        if self.beams and self.firmware is not None:
            raise UserError(f"{sc.path}: a beams scenario has no firmware to run")
        # a world that steps itself is run by its paper's package (host_tools/plugins.py)
        self._stepped = plugins.stepped_run(sc.world.kind) if self.beams else None
        given = {"seed": seed, "duration_s": duration_s, "tactile": tactile,
                 "runtime": None if runtime is None else self.runtime.value,
                 "firmware": None if self.firmware is None else str(firmware),
                 "firmware_runtime": None if self.firmware is None else self.firmware.runtime}
        # every override, in the trace, the summary and JUnit (``what_ran``)
        self.overrides: dict[str, Any] = {**{k: v for k, v in given.items() if v is not None},
                                          **(overrides or {})}
        self.tactile = (None if self.firmware is not None or self.beams
                        else tactile if tactile is not None
                        else sc.firmware.tactile if sc.firmware.tactile is not None
                        else ls.TACTILE_DEFAULT)
        # a GDB session halts the firmware for as long as its user likes: no wall-clock cap
        self.limits = (limits if limits is not None
                       else RunLimits(max_wall_s=math.inf) if gdb_port is not None
                       else RunLimits())
        self.trace = str(trace) if trace else None
        self._can_server, self._realtime = can_server, realtime
        self.world = None if self.beams else make_world(sc, self.seed)
        self.recorder: TraceRecorder | None = None
        self.live: Any = None
        if live_port is not None:
            from hexhil.trace.live import LiveServer

            self.live = LiveServer(live_port)
        if self.trace or live_port is not None:
            from hexhil.trace.recorder import Recorder

            meta = trace_metadata(sc, self.seed, self._runtime_name(), self.overrides)
            extra = ({"flush_interval_us": self.live.flush_interval_us}
                     if self.live is not None else {})
            try:
                self.recorder = Recorder(self.trace or os.devnull, meta, live=self.live,
                                         overwrite=overwrite, encode_in=self._encode_in(),
                                         protocol=models.protocol(sc.bus.model), **extra)
            except BaseException:
                self.close()
                raise
        self.sim: Simulator | None = None
        # a firmware of yours has the bus master's protocol check on (docs/firmware.md)
        self.check: MasterCheck | None = None
        if not self.beams:
            try:
                self.sim = Simulator(sc, self.seed, world=self.world, recorder=self.recorder,
                                     tactile=tactile, can_server=can_server,
                                     scene=self.recorder is not None, realtime=realtime)
                if self.firmware is not None and self.sim.bus is not None:
                    self.watch_master()
            except BaseException:
                self.close()
                raise

    def watch_master(self) -> MasterCheck:
        """The bus master's protocol check (hil/servobus/master_check.py) on this run: its
        violations go to the trace's ``/bus/violations`` and ``RunResult.violations``."""
        sim = self._firmware_sim()
        if self.check is None:
            self.check = MasterCheck(self.recorder.violation if self.recorder else None,
                                     models.protocol(self.scenario.bus.model))
            sim.bus.monitor = self.check
        return self.check

    def _encode_in(self) -> "EncodeIn":
        from hexhil.trace.windows import encode_in_for

        return encode_in_for(not self.beams and (
            self.firmware.own_process if self.firmware is not None
            else self.runtime is not Runtime.CPYTHON_INPROCESS))

    def _runtime_name(self) -> str:
        """What ran the firmware: its runtime, an ELF's or an executable's, none (beams)."""
        return (NO_RUNTIME if self.beams else self.firmware.runtime if self.firmware
                else self.runtime.value)

    def what_ran(self) -> dict[str, Any]:
        """The summary's account of the run's settings: the tactile rule as run (None: a
        firmware of yours, or a beams run) and every override."""
        return {"tactile": self.tactile, "overrides": dict(self.overrides)}

    # --- host nodes ---------------------------------------------------------------------
    def _firmware_sim(self) -> Simulator:
        if self.sim is None:
            raise UserError(f"{self.scenario.path}: a beams run has its own host nodes "
                            "(its paper's package); it takes no others")
        return self.sim

    def can_endpoint(self) -> Endpoint:
        """A host node's port on the run's CAN bus: it reads the frames the firmware sends
        (not the host's own, nor another node's) and sends frames the firmware receives."""
        return self._firmware_sim().can.endpoint("rx", hears="tx")

    @property
    def can(self) -> CanBus:
        """The run's CAN bus (hil/canbus/bus.py)."""
        return self._firmware_sim().can

    def add_node(self, node: HostNode) -> None:
        """Tick ``node`` on the run's clock, after the nodes added before it."""
        self._firmware_sim().add_node(node)

    def inject(self, kind: str, **params: Any) -> dict[str, Any]:
        """A named fault, now or at ``at_s`` (run time), as a ``[faults]`` entry: before
        ``run()`` or from a host node's tick (docs/servo-bus.md "Fault vocabulary")."""
        return self._firmware_sim().core.inject(kind, **params)

    def send_can(self, msg: "can.Message") -> None:
        """One frame from the host to the firmware, now (virtual time), as python-can's
        ``send(msg)`` takes it."""
        self._firmware_sim().send_can(*standard_frame(msg))

    # --- running ------------------------------------------------------------------------
    def run(self, wrap: Any = None, main: Any = None) -> RunResult:
        """Run to the end (``duration_s`` of virtual time, or the firmware's stop); the
        trace is complete when this returns. Ctrl-C (or SIGTERM) at any moment of it raises
        ``RunInterrupted`` with the run up to then, its trace closed and kept. With our
        firmware in process, ``wrap`` and ``main`` go to host_tools/in_process.py ``run``."""
        try:
            if self.beams:
                return self._traverse()
            if self.firmware is not None:
                result = self._firmware_sim().run(self.duration_s, firmware=self.firmware,
                                                  limits=self.limits)
            else:
                from hexhil import in_process

                result = in_process.run(self._firmware_sim(), self.duration_s,
                                        self.runtime.value, self.limits, wrap, main)
            if self.check is not None:
                result = dataclasses.replace(result, violations=self.check.summary())
            return result
        except RunInterrupted:
            raise
        except KeyboardInterrupt:    # before the lockstep loop began (a beams run's set-up)
            raise RunInterrupted(RunResult(self._runtime_name(), interrupted=True)) from None
        finally:
            self.close()

    def _traverse(self) -> RunResult:
        assert self._stepped is not None
        return self._stepped(self.scenario, self.seed, self.recorder, self._can_server,
                             self.recorder is not None, self._realtime)

    def close(self) -> None:
        """Close the trace (complete as far as the run went), then the live server; a
        simulator never run lets its CAN bus go too."""
        sim = getattr(self, "sim", None)   # None until made (close() runs on a failed start)
        if sim is not None:
            sim.core.shutdown()
        if self.recorder is not None:
            self.recorder.close()
        if self.live is not None:
            self.live.close()
            self.live = None
