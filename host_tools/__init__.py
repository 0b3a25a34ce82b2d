"""hexhil's public Python API, importable from one place (``import host_tools as hx``):
load a scenario, build and run it with host nodes of your own, record it, read the trace.
docs/api.md describes each name; examples/host_node.py uses them all.

Names resolve on first use (PEP 562), so ``hexhil``'s commands do not pay for the
simulator, MuJoCo and MCAP on start-up.
"""
from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

_WHERE = {
    # scenarios: typed, frozen, every default applied (hil/scenario/)
    "Scenario": "hil.scenario", "load_scenario": "hil.scenario",
    "Runtime": "hil.scenario", "WorldKind": "hil.scenario",
    **{name: "hil.scenario" for name in (
        "ScenarioInfo", "BusConfig", "FirmwareConfig", "GaitConfig", "FaultsConfig",
        "FaultEntry", "FaultKind", "WorldConfig", "Obstacle", "BeamsConfig",
        "TraversalConfig")},
    # the seams a run takes (hil/seams.py)
    "HostNode": "hil.seams", "FirmwareWorld": "hil.seams", "SteppedWorld": "hil.seams",
    "TraceRecorder": "hil.seams", "Actuator": "hil.seams", "CanGateway": "hil.seams",
    "CanHub": "hil.seams", "CanPort": "hil.seams", "ServoLine": "hil.seams",
    "LinkHost": "hil.seams",
    # a run and its result
    "Run": "host_tools.lockstep_run", "RunResult": "hil.run_result",
    "FirmwareEnding": "hil.run_result", "Ending": "hil.run_result",
    "FirmwareStats": "hil.run_result", "BodyDisplacement": "hil.run_result",
    "HexapodOutcome": "hil.run_result", "BeamsOutcome": "hil.run_result",
    "RunInterrupted": "hil.run_result",
    "scenario_of_trace": "host_tools.lockstep_run",
    # a master that is not ours, in real time (hexhil bus)
    "RealTimeRun": "host_tools.realtime_run", "Pty": "host_tools.realtime_run",
    "Tcp": "host_tools.realtime_run", "SerialPort": "host_tools.realtime_run",
    "Rfc2217": "host_tools.realtime_run", "ServeResult": "host_tools.realtime_run",
    # traces
    "open_trace": "host_tools.trace.reader", "Trace": "host_tools.trace.reader",
    "TraceMessage": "host_tools.trace.reader",
    "Recorder": "host_tools.trace.recorder", "EncodeIn": "host_tools.trace.recorder",
    # errors a user can act on: one line, no traceback
    "UserError": "protocol.errors", "BadValue": "protocol.errors", "BadFile": "protocol.errors",
}
# parse_scenario: a scenario from a dict as TOML reads it (tests and sweeps build them);
# can_message: a frame of our DBC as a python-can message (what a port's send takes)
_RENAMED = {"parse_scenario": ("hil.scenario", "parse"), "can_message": ("hil.canbus.bus", "message")}
# the CAN frames' encoder and decoder (protocol/can_frames.py: encode, decode, FRAMES)
_MODULES = {"can_frames": "protocol.can_frames"}

__all__ = sorted([*_WHERE, *_RENAMED, *_MODULES])


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        return getattr(importlib.import_module(_WHERE[name]), name)
    if name in _RENAMED:
        module, attr = _RENAMED[name]
        return getattr(importlib.import_module(module), attr)
    if name in _MODULES:
        return importlib.import_module(_MODULES[name])
    raise AttributeError(f"module 'host_tools' has no attribute {name!r}")


def __dir__() -> list[str]:
    return __all__


if TYPE_CHECKING:   # for type checkers and editors: the same names, eagerly
    from hil.run_result import (BeamsOutcome, BodyDisplacement, Ending, FirmwareEnding,
                                FirmwareStats, HexapodOutcome, RunInterrupted, RunResult)
    from hil.scenario import (BeamsConfig, BusConfig, FaultEntry, FaultKind, FaultsConfig,
                              FirmwareConfig, GaitConfig, Obstacle, Runtime, Scenario,
                              ScenarioInfo, TraversalConfig, WorldConfig, WorldKind,
                              load_scenario)
    from hil.canbus.bus import message as can_message
    from hil.scenario import parse as parse_scenario
    from hil.seams import (Actuator, CanGateway, CanHub, CanPort, FirmwareWorld, HostNode,
                           LinkHost, ServoLine, SteppedWorld, TraceRecorder)
    from host_tools.realtime_run import Pty, RealTimeRun, Rfc2217, SerialPort, ServeResult, Tcp
    from host_tools.lockstep_run import Run, scenario_of_trace
    from host_tools.trace.reader import Trace, TraceMessage, open_trace
    from host_tools.trace.recorder import EncodeIn, Recorder
    from protocol import can_frames
    from protocol.errors import BadFile, BadValue, UserError
