"""hexhil's public Python API, importable from one place (``import hexhil as hx``):
load a scenario, build and run it with host nodes of your own, record it, read the trace.
docs/api.md describes each name; examples/host_node.py uses them all.

Names resolve on first use (PEP 562), so ``hexhil``'s commands do not pay for the
simulator, MuJoCo and MCAP on start-up.
"""
from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from . import chip_names

chip_names.install()   # before hexhil.protocol or hexhil.firmware is first imported

_WHERE = {
    # scenarios: typed, frozen, every default applied (hil/scenario/)
    "Scenario": "hexhil.hil.scenario", "load_scenario": "hexhil.hil.scenario",
    "Runtime": "hexhil.hil.scenario", "WorldKind": "hexhil.hil.scenario",
    **{name: "hexhil.hil.scenario" for name in (
        "ScenarioInfo", "BusConfig", "FirmwareConfig", "GaitConfig", "FaultsConfig",
        "FaultEntry", "FaultKind", "WorldConfig", "Obstacle", "BeamsConfig",
        "TraversalConfig")},
    # the seams a run takes (hil/seams.py)
    "HostNode": "hexhil.hil.seams", "FirmwareWorld": "hexhil.hil.seams", "SteppedWorld": "hexhil.hil.seams",
    "TraceRecorder": "hexhil.hil.seams", "Actuator": "hexhil.hil.seams", "CanGateway": "hexhil.hil.seams",
    "CanHub": "hexhil.hil.seams", "CanPort": "hexhil.hil.seams", "ServoLine": "hexhil.hil.seams",
    "LinkHost": "hexhil.hil.seams",
    # a run and its result
    "Run": "hexhil.lockstep_run", "RunResult": "hexhil.hil.run_result",
    "FirmwareEnding": "hexhil.hil.run_result", "Ending": "hexhil.hil.run_result",
    "FirmwareStats": "hexhil.hil.run_result", "BodyDisplacement": "hexhil.hil.run_result",
    "HexapodOutcome": "hexhil.hil.run_result", "BeamsOutcome": "hexhil.hil.run_result",
    "RunInterrupted": "hexhil.hil.run_result",
    "scenario_of_trace": "hexhil.trace.run_metadata", "RunLimits": "hexhil.hil.run.limits",
    # the bus master's protocol check a run of a firmware of yours keeps (Run.check)
    "MasterCheck": "hexhil.hil.servobus.master_check",
    # a master that is not ours, in real time (hexhil bus)
    "RealTimeRun": "hexhil.realtime_run", "Pty": "hexhil.realtime_run",
    "Tcp": "hexhil.realtime_run", "SerialPort": "hexhil.realtime_run",
    "Rfc2217": "hexhil.realtime_run", "ServeResult": "hexhil.realtime_run",
    # traces
    "open_trace": "hexhil.trace.reader", "Trace": "hexhil.trace.reader",
    "TraceMessage": "hexhil.trace.reader",
    "Recorder": "hexhil.trace.recorder", "EncodeIn": "hexhil.trace.recorder",
    # errors a user can act on: one line, no traceback
    "UserError": "hexhil.protocol.errors", "BadValue": "hexhil.protocol.errors", "BadFile": "hexhil.protocol.errors",
    "TimedOut": "hexhil.protocol.errors",
}
# parse_scenario: a scenario from a dict as TOML reads it (tests and sweeps build them);
# can_message: a frame of our DBC as a python-can message (what a port's send takes)
_RENAMED = {"parse_scenario": ("hexhil.hil.scenario", "parse"), "can_message": ("hexhil.hil.canbus.bus", "message")}
# the CAN frames' encoder and decoder (protocol/can_frames.py: encode, decode, FRAMES)
_MODULES = {"can_frames": "hexhil.protocol.can_frames"}

__all__ = sorted([*_WHERE, *_RENAMED, *_MODULES])


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        return getattr(importlib.import_module(_WHERE[name]), name)
    if name in _RENAMED:
        module, attr = _RENAMED[name]
        return getattr(importlib.import_module(module), attr)
    if name in _MODULES:
        return importlib.import_module(_MODULES[name])
    raise AttributeError(f"module 'hexhil' has no attribute {name!r}")


def __dir__() -> list[str]:
    return __all__


if TYPE_CHECKING:   # for type checkers and editors: the same names, eagerly
    from hexhil.hil.run_result import (BeamsOutcome, BodyDisplacement, Ending, FirmwareEnding,
                                FirmwareStats, HexapodOutcome, RunInterrupted, RunResult)
    from hexhil.hil.scenario import (BeamsConfig, BusConfig, FaultEntry, FaultKind, FaultsConfig,
                              FirmwareConfig, GaitConfig, Obstacle, Runtime, Scenario,
                              ScenarioInfo, TraversalConfig, WorldConfig, WorldKind,
                              load_scenario)
    from hexhil.hil.canbus.bus import message as can_message
    from hexhil.hil.scenario import parse as parse_scenario
    from hexhil.hil.seams import (Actuator, CanGateway, CanHub, CanPort, FirmwareWorld, HostNode,
                           LinkHost, ServoLine, SteppedWorld, TraceRecorder)
    from hexhil.realtime_run import Pty, RealTimeRun, Rfc2217, SerialPort, ServeResult, Tcp
    from hexhil.lockstep_run import Run
    from hexhil.trace.run_metadata import scenario_of_trace
    from hexhil.trace.reader import Trace, TraceMessage, open_trace
    from hexhil.trace.recorder import EncodeIn, Recorder
    from hexhil.protocol import can_frames
    from hexhil.protocol.errors import BadFile, BadValue, TimedOut, UserError
