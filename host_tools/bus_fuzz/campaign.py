"""A fuzzing campaign: inputs drawn and mutated from a corpus kept by coverage, judged by the
case's expectations, each distinct failure shrunk by delta debugging and written out as a
scenario whose ``[faults]`` replay it.

Rounds of ``BATCH`` inputs: each round's inputs are drawn from the corpus as it stood when
the round began, by an RNG seeded with the campaign's seed and the round's number, and
their verdicts are taken in input order. Where the inputs ran (one server, ``jobs`` of
them, a Dask cluster) changes nothing: a seed and a budget of runs give the same campaign.
A time budget (``time_s``) ends it after the round that passes it.
"""
from __future__ import annotations

import dataclasses
import json
import math
import random
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

from hexhil.hil.scenario.faults_section import FaultKind
from hexhil.protocol.dynamixel import models
from hexhil.bus_fuzz import execution, fork_server
from hexhil.bus_fuzz.execution import Execution, Target
from hexhil.bus_fuzz.mutations import (DEFAULT_KINDS, Input, Mutation, Mutator, Vocabulary,
                                           faults_table, ordered)
from hexhil.expect import spec
from hexhil.protocol.errors import BadFile, BadValue, UserError

BATCH = 16                # inputs a round
SHRINK_RUNS = 120         # executions at most to shrink one failure
PER_FAILURE = 4           # failing inputs kept a failure, of different kinds of faults


@dataclass(frozen=True)
class Settings:
    """A campaign: the expectation file, the firmware, the budget, where it runs."""

    expect: str
    scenario: str | None = None          # fuzz this scenario (default: the case's own)
    window_s: float = 1.0                # faults start here (the state saved after boot)
    runs: int | None = 200
    time_s: float | None = None
    seed: int = 0
    jobs: int = 1
    scheduler: str | None = None
    firmware: str | None = None          # as hexhil run --firmware (fresh runs)
    main_file: str | None = None         # a module with main(board), in process
    kinds: tuple[FaultKind, ...] = DEFAULT_KINDS
    coverage: bool = True
    out: str | None = None               # reproducers and traces here
    shrink: bool = True


@dataclass
class Finding:
    """One distinct failure: its labels, the input that first showed it, that input shrunk."""

    failures: tuple[str, ...]
    details: tuple[str, ...]
    found_at: int                         # the execution that found it (1-based)
    first: Input
    shrunk: Input = ()
    scenario: str | None = None
    expect: str | None = None
    trace: str | None = None
    replayed: bool | None = None          # the written reproducer, run fresh, fails the same

    def as_dict(self) -> dict[str, Any]:
        return {"failures": list(self.failures), "details": list(self.details),
                "found_at": self.found_at, "faults": [str(m) for m in self.first],
                "shrunk": [str(m) for m in self.shrunk], "scenario": self.scenario,
                "expect": self.expect, "trace": self.trace, "replayed": self.replayed}


@dataclass
class Report:
    """What a campaign did: executions, their rate, the features reached, the findings."""

    executions: int = 0
    shrink_executions: int = 0
    wall_s: float = 0.0
    child_cpu_s: float = 0.0              # the forked children's CPU, all executions'
    features: int = 0
    baseline_features: int = 0
    corpus: int = 0
    findings: list[Finding] = field(default_factory=list)

    @property
    def rate(self) -> float:
        """Executions a second, the shrinking's included (they cost the same)."""
        done = self.executions + self.shrink_executions
        return done / self.wall_s if self.wall_s > 0 else 0.0

    def as_dict(self) -> dict[str, Any]:
        return {"executions": self.executions, "shrink_executions": self.shrink_executions,
                "wall_s": round(self.wall_s, 3), "executions_per_s": round(self.rate, 2),
                "child_cpu_s": round(self.child_cpu_s, 3),
                "features": self.features, "baseline_features": self.baseline_features,
                "corpus": self.corpus, "findings": [f.as_dict() for f in self.findings]}


Progress = Callable[[Report], None]


class _Runner:
    """Runs lists of inputs where the settings say: local servers, or Dask batches."""

    def __init__(self, target: Target, settings: Settings) -> None:
        self.target, self.settings = target, settings
        self.servers: fork_server.Servers | None = None
        self.client: Any = None
        if settings.scheduler:
            from hexhil.executor import dask_client

            self.client = dask_client(settings.scheduler)
        else:
            self.servers = fork_server.Servers(target, settings.jobs)

    def run(self, inputs: Sequence[Input]) -> list[Execution]:
        if self.servers is not None:
            return self.servers.run(list(inputs))
        parts = max(1, min(len(inputs), self.settings.jobs))
        size = math.ceil(len(inputs) / parts)
        chunks = [list(inputs[i:i + size]) for i in range(0, len(inputs), size)]
        futures = self.client.map(fork_server.run_batch, [self.target] * len(chunks), chunks,
                                  pure=False)
        return [e for chunk in self.client.gather(futures) for e in chunk]

    def close(self) -> None:
        if self.servers is not None:
            self.servers.close()
        if self.client is not None:
            self.client.close()


def vocabulary(target: Target, kinds: Sequence[FaultKind]) -> Vocabulary:
    """The faults a case's scenario can take: its servos' IDs, its window."""
    bus = target.case.scenario.bus
    ids = tuple(range(bus.first_id, bus.first_id + bus.servos))
    end_s = target.case.duration_s
    if not 0 < target.window_s < end_s:
        raise BadValue(f"window_s: the faults must start inside the case's {end_s:g} s "
                       f"(window_s {target.window_s:g} s)", params=("window_s",))
    return Vocabulary(tuple(kinds), ids, target.window_s, end_s,
                      protocol=models.protocol(bus.model))


def load_target(settings: Settings, fork: bool = True) -> Target:
    """The settings' case and firmware, checked before anything runs."""
    case = spec.load(settings.expect)
    if settings.scenario is not None:     # as hexhil margin: the scenario's name and seed
        from hexhil.hil import scenario as scenario_mod

        sc = scenario_mod.load_scenario(settings.scenario)
        case = dataclasses.replace(case, scenario=sc, name=sc.scenario.name or case.name,
                                   seed=sc.scenario.seed)
    if settings.firmware is not None and settings.main_file is not None:
        raise UserError("give firmware or main_file, not both",
                        params=("firmware", "main_file"))
    if settings.runs is None and settings.time_s is None:
        raise UserError("give a budget: runs or time_s", params=("runs", "time_s"))
    if settings.runs is not None and settings.runs < 1 or settings.jobs < 1:
        raise BadValue("runs and jobs must be at least 1", params=("runs", "jobs"))
    firmware = settings.firmware or case.firmware
    if firmware is not None:
        from hexhil.hil.link.served_firmware import served_firmware

        served_firmware(firmware)
        firmware = str(Path(firmware).resolve())
    main_file = str(Path(settings.main_file).resolve()) if settings.main_file else None
    if main_file is not None:
        from hexhil.in_process import load_main

        load_main(main_file)
    return Target(case, settings.window_s, firmware, main_file, settings.coverage, fork)


def fuzz(settings: Settings, progress: Progress | None = None) -> Report:
    """Run a campaign; every finding shrunk and, with ``settings.out``, written out."""
    target = load_target(settings)
    vocab = vocabulary(target, settings.kinds)
    report = Report()
    wall0 = time.perf_counter()
    runner = _Runner(target, settings)
    try:
        base = runner.run([()])[0]
        report.executions, report.child_cpu_s = 1, base.cpu_s
        if base.failed:
            raise UserError(f"{settings.expect}: the case fails with no fault injected ("
                            + "; ".join(base.details) + "): fix it before fuzzing it")
        seen = set(base.features)
        report.baseline_features = len(seen)
        corpus: list[Input] = [()]
        by_failure: dict[tuple[str, ...], list[Finding]] = {}
        k = 0
        while not _spent(settings, report, wall0):
            rng = random.Random(f"{settings.seed}:round:{k}")
            mutator = Mutator(vocab, rng)
            n = BATCH if settings.runs is None else min(BATCH, settings.runs - report.executions)
            inputs = [mutator.fresh() if rng.random() < 0.25 or len(corpus) == 1 else
                      mutator.mutate(rng.choice(corpus), rng.choice(corpus))
                      for _ in range(n)]
            for faults, e in zip(inputs, runner.run(inputs)):
                report.executions += 1
                report.child_cpu_s += e.cpu_s
                new = e.features - seen
                if new:
                    seen |= new
                    corpus.append(faults)
                group = by_failure.setdefault(e.failures, []) if e.failed else []
                if e.failed and len(group) < PER_FAILURE and _kinds(faults) not in [
                        _kinds(g.first) for g in group]:
                    group.append(Finding(e.failures, e.details, report.executions, faults))
                    report.findings.append(group[-1])
            k += 1
            report.features, report.corpus = len(seen), len(corpus)
            report.wall_s = time.perf_counter() - wall0
            if progress is not None:
                progress(report)
        if settings.shrink:
            for f in report.findings:
                f.shrunk, used = shrink(f.first, f.failures, runner.run)
                report.shrink_executions += used
            report.findings = _distinct(report.findings)
    finally:
        runner.close()
    report.wall_s = time.perf_counter() - wall0
    if settings.out is not None:
        write_findings(target, settings, report)
    return report


def _kinds(faults: Input) -> frozenset[FaultKind]:
    return frozenset(m.kind for m in faults)


def _distinct(findings: list[Finding]) -> list[Finding]:
    """One finding a failure and kinds of faults that cause it, once shrunk: the first
    found of those that shrank to the same."""
    out: list[Finding] = []
    for f in findings:
        if all((g.failures, _kinds(g.shrunk)) != (f.failures, _kinds(f.shrunk)) for g in out):
            out.append(f)
    return out


def _spent(settings: Settings, report: Report, wall0: float) -> bool:
    if settings.runs is not None and report.executions >= settings.runs:
        return True
    return settings.time_s is not None and time.perf_counter() - wall0 >= settings.time_s


def shrink(faults: Input, failures: tuple[str, ...],
           run: Callable[[Sequence[Input]], list[Execution]],
           budget: int = SHRINK_RUNS) -> tuple[Input, int]:
    """Delta debugging (Zeller's ddmin) over the faults: the fewest that still fail with
    the same ``failures``; each step's candidates run as one batch, the first that fails
    in their order is taken (so the result does not depend on where they ran). Returns
    the faults kept and the executions spent."""
    items = list(faults)
    used, n = 0, 2
    while len(items) >= 2 and used < budget:
        size = math.ceil(len(items) / n)
        parts = [items[i:i + size] for i in range(0, len(items), size)]
        candidates = parts + ([[m for j, p in enumerate(parts) if j != i for m in p]
                               for i in range(len(parts))] if len(parts) > 2 else [])
        verdicts = run([ordered(c) for c in candidates])
        used += len(candidates)
        hit = next((i for i, e in enumerate(verdicts) if e.failures == failures), None)
        if hit is None:
            if n >= len(items):
                break
            n = min(len(items), 2 * n)
        elif hit < len(parts):
            items, n = candidates[hit], 2
        else:
            items, n = candidates[hit], max(n - 1, 2)
    return ordered(items), used


# --- reproducers ---------------------------------------------------------------------------
def write_findings(target: Target, settings: Settings, report: Report) -> None:
    """Each finding as ``finding-N.toml`` (the scenario, its faults the shrunk input) and
    ``finding-N-expect.toml`` (the case's expectations on it), its trace beside them, then
    each reproducer run fresh (no fork) to check it fails the same way."""
    out = Path(settings.out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BadFile(f"out {out}: cannot make the folder ({exc.strerror})",
                      params=("out",)) from None
    raw = tomllib.loads(Path(settings.expect).read_text(encoding="utf-8"))
    for k, f in enumerate(report.findings, 1):
        faults = f.shrunk or f.first
        sc = target.case.scenario.overlay({"faults": faults_table(faults)})
        scenario_path = out / f"finding-{k}.toml"
        scenario_path.write_text(_header(f, faults) + toml_text(sc.as_toml_data()))
        case = dict(raw.get("case", {}))
        case["scenario"] = scenario_path.name
        case["duration_s"] = target.case.duration_s
        case["seed"] = target.case.seed
        case.pop("firmware", None)
        if target.firmware is not None:
            case["firmware"] = target.firmware
        elif target.main_file is None:
            case["python"] = "cpython-inprocess"
        expect_path = out / f"finding-{k}-expect.toml"
        expect_path.write_text(toml_text({"case": case}) + "".join(
            "\n[[expect]]\n" + "".join(f"{k} = {_value(v)}\n" for k, v in e.items())
            for e in raw.get("expect", [])))
        trace = out / f"finding-{k}.mcap"
        replay = execution.fresh(
            Target(spec.load(expect_path), target.window_s, target.firmware,
                   target.main_file, False, fork=False), (), keep=trace)
        f.scenario, f.expect, f.trace = str(scenario_path), str(expect_path), str(trace)
        f.replayed = replay.failures == f.failures


def _header(f: Finding, faults: Input) -> str:
    lines = ["# Found by hexhil fuzz: fails with " + "; ".join(f.failures),
             *(f"#   {d}" for d in f.details),
             f"# {len(faults)} fault(s) of the {len(f.first)} that found it"]
    return "\n".join(lines) + "\n"


def toml_text(data: dict[str, Any]) -> str:
    """Scenario-shaped data as TOML: tables of scalars, lists and inline tables."""
    out = [f"{k} = {_value(v)}" for k, v in data.items() if not isinstance(v, dict)]
    for section, body in data.items():
        if isinstance(body, dict):
            out.append(f"\n[{section}]")
            out += [f"{k} = {_value(v)}" for k, v in body.items()]
    return "\n".join(out).lstrip("\n") + "\n"


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {_value(x)}" for k, x in v.items()) + "}"
    raise BadValue(f"cannot write {v!r} as TOML")


def replay_command(f: Finding, settings: Settings) -> str:
    """The ``hexhil test`` line that replays a finding."""
    extra = f" --in-process {settings.main_file}" if settings.main_file else ""
    return f"hexhil test {f.expect}{extra}"


def mutation_kinds(names: Sequence[str]) -> tuple[FaultKind, ...]:
    """``--kinds`` names as fault kinds (one line naming an unknown one)."""
    out = []
    for name in names:
        try:
            out.append(FaultKind(name))
        except ValueError:
            raise BadValue(f"kinds: unknown fault kind {name!r} (known: "
                           f"{', '.join(k.value for k in DEFAULT_KINDS)})",
                           params=("kinds",)) from None
    return tuple(out)


__all__ = ["Settings", "Report", "Finding", "fuzz", "shrink", "Mutation"]
