"""What a trace says about the run that made it: the scenario as run, the seed, the firmware
runtime and the overrides (``trace_metadata``), and the scenario and seed read back from
it (``scenario_of_trace``), for a lockstep run and a real-time one alike."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from hexhil.hil import scenario as scenario_mod
from hexhil.hil.scenario import Scenario
from hexhil.protocol.errors import BadFile, BadValue


def trace_metadata(sc: Scenario, seed: int, runtime: str,
                   overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """What a trace says about its run: the scenario's name and its data as run (every
    override applied: ``as_run``), seed, runtime, and the overrides themselves (what the
    command or the caller changed: tactile, seed, duration, firmware, bus timing...)."""
    overrides = dict(overrides or {})
    return {"scenario": sc.path, "seed": seed, "firmware_runtime": runtime,
            "scenario_data": as_run(sc, seed, overrides), "overrides": overrides}


def as_run(sc: Scenario, seed: int, overrides: dict[str, Any]) -> dict[str, Any]:
    """The scenario's data with what a run changed written in, so that ``scenario_of_trace``
    gives what was run: its seed, its ``duration_s`` and its ``firmware.tactile``."""
    changes: dict[str, dict[str, Any]] = {"scenario": {"seed": seed}}
    if "duration_s" in overrides:
        changes["scenario"]["duration_s"] = overrides["duration_s"]
    if "tactile" in overrides:
        changes["firmware"] = {"tactile": overrides["tactile"]}
    return sc.overlay(changes).as_toml_data()


def scenario_of_trace(metadata: dict[str, str], where: str) -> tuple[Scenario, int]:
    """The scenario and seed a trace ran, from its metadata (``trace_metadata``); a trace
    recorded before the scenario rode along names a file, read if this machine has it."""
    try:
        seed = int(metadata.get("seed", "0"))
        data = json.loads(metadata["scenario_data"]) if "scenario_data" in metadata else None
    except (ValueError, RecursionError):
        raise BadValue(f"{where}: unreadable run metadata") from None
    path = metadata.get("scenario", "")
    if data is not None:
        return scenario_mod.parse(data, path or where), seed
    if not path or not Path(path).is_file():
        raise BadFile(f"{where}: the trace names no scenario file this machine has "
                      f"({path or 'none'})")
    return scenario_mod.load_scenario(path), seed
