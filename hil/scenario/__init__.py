"""Scenario files (TOML): one loader, one schema, typed sections, one-line errors.

Each section's keys and types are declared in ``SCHEMA`` (schema.py); each section's
defaults and rules sit beside its frozen type (sections.py, world.py, faults.py; seed 000's
in beams.py), applied once by ``parse``, so ``hexhil run``, ``hexhil bus``, the experiments
and the tests build the same rig from the same file. Everything below the loader takes the
``Scenario`` or one of its sections; only this package reads the data as written.
"""
from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from hexhil.hil.scenario.beams import BeamsConfig, TraversalConfig
from hexhil.hil.scenario.faults_section import FaultEntry, FaultKind, FaultsConfig
from hexhil.hil.scenario.rules import SCHEMA, check_table, optional
from hexhil.hil.scenario.sections import (DEFAULT_BAUD, DEFAULT_DURATION_S, GAITS, MAX_DURATION_S,
                                   RETURN_DELAY_MAX_US, SEED_MAX, BusConfig, FirmwareConfig,
                                   GaitConfig, Runtime, ScenarioInfo, check_duration, check_seed,
                                   check_span)
from hexhil.hil.scenario.world_section import Obstacle, WorldConfig, WorldKind
from hexhil.protocol import link_schema as ls
from hexhil.protocol.dynamixel import models
from hexhil.protocol.errors import BadFile, BadValue


@dataclass(frozen=True)
class Scenario:
    """A checked scenario: its typed sections, every default applied, and (for a trace's
    metadata and ``overlay``) the data as written, with the file's ``text`` when it came
    from one."""

    path: str
    scenario: ScenarioInfo
    bus: BusConfig
    firmware: FirmwareConfig
    gait: GaitConfig
    faults: FaultsConfig
    world: WorldConfig
    beams: BeamsConfig
    traversal: TraversalConfig
    written: dict[str, Any] = field(repr=False, compare=False)
    text: str | None = field(default=None, repr=False, compare=False)

    @property
    def name(self) -> str:
        return self.scenario.name or Path(self.path).stem

    def as_toml_data(self) -> dict[str, Any]:
        """The sections as written, without the loader's ``_path`` (for a trace's metadata)."""
        return {k: v for k, v in self.written.items() if not k.startswith("_")}

    def overlay(self, changes: Mapping[str, Mapping[str, Any]]) -> "Scenario":
        """This scenario with ``changes`` (section -> key -> value) written over it, checked
        again: a value replaces the written one, a list extends it (fault entries)."""
        data = {k: dict(v) if isinstance(v, dict) else v for k, v in self.written.items()}
        for section, values in changes.items():
            body = data.setdefault(section, {})
            for key, value in values.items():
                old = body.get(key)
                body[key] = [*old, *value] if isinstance(old, list) and isinstance(value, list) \
                    else value
        return parse(data, self.path)

    def firmware_settings(self, tactile: bool | None = None) -> dict[str, Any]:
        """The firmware/config.py overrides this scenario asks for (the link's hello config,
        keys from protocol/link_schema.py CONFIG): the keys the file sets, the gait always;
        ``tactile`` overrides the file's rule."""
        fw, bus, gait = self.written["firmware"], self.written["bus"], self.gait
        out: dict[str, Any] = {k: fw[k] for k in (ls.CYCLE_HZ, ls.TACTILE_ON, ls.SERVO_LOST_S,
                                                   ls.READS_PER_CYCLE) if k in fw}
        out[ls.GAIT] = gait.name
        out[ls.PERIOD_S] = gait.period_s
        for key in (ls.STEP_LENGTH_M, ls.STEP_HEIGHT_M, ls.MAX_OBSTACLE_HEIGHT_M,
                    ls.DIRECTION_DEG):
            if getattr(gait, key) is not None:
                out[key] = getattr(gait, key)
        for key in (ls.FIRST_ID, ls.BAUD):
            if key in bus:
                out[key] = bus[key]
        version = models.protocol(self.bus.model)
        if version != models.protocol(models.DEFAULT):   # the firmware's default stays unsaid
            out[ls.PROTOCOL] = version
        if tactile is not None:
            out[ls.TACTILE_ON] = tactile
        return out


def _sections(data: dict[str, Any], where: str) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for section, body in data.items():
        if section == "_path":
            continue
        if section not in SCHEMA:
            raise BadValue(f"{where}: unknown section '[{section}]' "
                           f"(known: {', '.join(sorted(SCHEMA))})")
        if not isinstance(body, dict):
            raise BadValue(f"{where}: '{section}' must be a table ([{section}])")
        out[section] = check_table(where, body, optional(SCHEMA[section]), f"{section}.")
    for section in SCHEMA:
        out.setdefault(section, {})
    out["_path"] = where
    return out


def parse(data: dict[str, Any], path: str | Path | None = None,
          text: str | None = None) -> Scenario:
    """Every key, type, default and rule of a scenario (a dict as TOML reads it)."""
    if isinstance(data, Scenario):
        return data
    where = str(path if path is not None else data.get("_path", "scenario"))
    d = _sections(data, where)
    gait = GaitConfig.parse(where, d["gait"])
    world = WorldConfig.parse(where, d["world"], gait.distance_m)
    return Scenario(
        where, ScenarioInfo.parse(where, d["scenario"]), BusConfig.parse(where, d["bus"]),
        FirmwareConfig.parse(where, d["firmware"]), gait,
        FaultsConfig.parse(where, d["faults"]), world,
        BeamsConfig.parse(where, d["beams"], world.kind is WorldKind.BEAMS),
        TraversalConfig.parse(where, d["traversal"]), d, text)


def toml_data(text: str, where: str | Path) -> dict[str, Any]:
    """TOML ``text`` read, or one line: not TOML, or nested deeper than Python's stack."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise BadValue(f"{where}: not valid TOML: {exc}") from None
    except RecursionError:
        raise BadValue(f"{where}: not valid TOML: arrays or tables nested too deeply") from None


def read_toml_file(path: str | Path, what: str) -> str:
    """The text of the TOML file ``path`` (a ``what`` file: scenario, expectation), or
    one line: missing, not a regular file (a FIFO would block, a device never ends),
    unreadable."""
    p = Path(path)
    try:
        if p.exists() and not p.is_file() and not p.is_dir():
            raise BadFile(f"{p}: not a regular file (a {what} file is a .toml file)")
        return p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise BadFile(f"{p}: {what} file not found") from None
    except (IsADirectoryError, PermissionError, UnicodeDecodeError) as exc:
        raise BadFile(f"{p}: cannot read {what} ({exc.__class__.__name__})") from None


def from_text(text: str, path: str | Path) -> Scenario:
    """A scenario from its TOML ``text`` (a trace's metadata keeps it); ``path`` names it.
    An empty one (no table, no key) is refused: it would run with no world at all."""
    data = toml_data(text, path)
    if not data:
        raise BadValue(f"{path}: an empty scenario (no [scenario], [world] or other table); "
                        "start from one in scenarios/, e.g. scenarios/flat-tripod.toml")
    try:
        return parse(data, path, text)
    except RecursionError:
        raise BadValue(f"{path}: a value nested too deeply") from None


def load_scenario(path: str | Path) -> Scenario:
    """Read and check a scenario file."""
    return from_text(read_toml_file(path, "scenario"), Path(path))


__all__ = ["SCHEMA", "Scenario", "ScenarioInfo", "BusConfig", "FirmwareConfig", "GaitConfig",
           "FaultsConfig", "FaultEntry", "FaultKind", "WorldConfig", "Obstacle", "BeamsConfig",
           "TraversalConfig", "Runtime", "WorldKind", "GAITS", "DEFAULT_BAUD",
           "DEFAULT_DURATION_S", "MAX_DURATION_S", "RETURN_DELAY_MAX_US", "SEED_MAX",
           "check_duration", "check_seed", "check_span", "parse", "from_text", "load_scenario",
           "read_toml_file", "toml_data"]
