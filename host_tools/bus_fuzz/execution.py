"""Running the fuzzer's inputs: one execution an input, judged, with the features it reached.

A firmware in this process (ours, or a module of the user's with ``main(board)``) runs on
the fork server (host_tools/bus_fuzz/fork_server.py): booted once, forked at the window
for each input. Any other firmware (the virtual board, an executable, an ELF) gets a fresh
run an input (``fresh``), the faults written into the scenario, as ``hexhil test`` would
run it; so does every reproducer, to check it fails the same way without the fuzzer.
"""
from __future__ import annotations

import math
import shutil
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Sequence

from hexhil.hil.run.limits import RunLimits
from hexhil import in_process
from hexhil.bus_fuzz import line_probes
from hexhil.bus_fuzz.features import PacketSequence, elf_lines, line_features
from hexhil.bus_fuzz.mutations import Input, faults_table
from hexhil.expect.spec import Case, Kind
from hexhil.expect.verdicts import Outcome, evaluate
from hexhil.hil.link.firmware_process import ROOT


@dataclass(frozen=True)
class Target:
    """What is fuzzed: the case (its expectations judge), the firmware (ours in process by
    default; ``firmware`` as ``hexhil run --firmware``; ``main_file``, a module with
    ``main(board)`` run in process like ours), and where the window starts."""

    case: Case
    window_s: float                      # faults start at or after this
    firmware: str | None = None
    main_file: str | None = None
    coverage: bool = True                # line coverage as a feature (in process, an ELF)
    fork: bool = True                    # in process: fork after boot (False: fresh runs)

    @property
    def in_process(self) -> bool:
        return self.firmware is None


@dataclass(frozen=True)
class Execution:
    """One input's verdict: what failed (sorted labels; empty: it passed), the failures'
    measured values, the features it reached, its wall time and (a forked child's) the CPU
    time it took, exit included."""

    failures: tuple[str, ...]
    details: tuple[str, ...]
    features: frozenset[int]
    wall_s: float
    cpu_s: float = 0.0

    @property
    def failed(self) -> bool:
        return bool(self.failures)


def judge(case: Case, summary: dict[str, Any], outcomes: Sequence[Outcome]
          ) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The failures of one run (``outcomes``: its expectations' verdicts): each failed
    expectation, a firmware that did not complete (a crash, a hang, an early exit) and an
    exception the expectations do not judge."""
    failures: dict[str, str] = {}
    for o in outcomes:
        if not o.passed:
            failures[f"expect: {o.name}"] = f"measured {o.measured}; limit {o.limit}"
    ending = summary.get("ending") or {}
    if ending.get("kind", "completed") != "completed":
        failures[f"firmware {ending['kind']}"] = ending.get("reason", "")
    judged = any(e.kind is Kind.NO_EXCEPTION for e in case.expectations)
    if summary.get("unhandled_exceptions") and not judged:
        failures["firmware exception"] = f"{summary['unhandled_exceptions']} exceptions"
    names = tuple(sorted(failures))
    return names, tuple(f"{n}: {failures[n]}" for n in names)


# --- one run ----------------------------------------------------------------------------
def run_input(target: Target, faults: Input, trace: Path, wrap: Any = None,
              coverage: str | None = None, setup: Any = None) -> dict[str, Any]:
    """The case's run, the faults in its scenario; with ``wrap`` (the fork server) none:
    the children inject them, and the run has no wall-clock cap: the server's run waits
    for inputs as long as the campaign lasts (a child's hang is ``HANG_WALL_S``'s)."""
    from hexhil.expect.case_runs import run_scenario

    case = target.case
    scenario = case.scenario
    if faults and wrap is None:       # a fresh run: the faults are the scenario's
        scenario = scenario.overlay({"faults": faults_table(faults)})
    main = in_process.load_main(target.main_file) if target.main_file else None
    judged = any(e.kind is Kind.PROTOCOL for e in case.expectations)
    return run_scenario(scenario, case.seed, case.duration_s,
                        "cpython-inprocess" if target.in_process else case.python,
                        case.tactile, trace, sends=case.sends, firmware=target.firmware,
                        coverage=coverage, wrap=wrap, main=main, master_check=judged,
                        limits=None if wrap is None else RunLimits(max_wall_s=math.inf),
                        setup=setup)[0]


def fresh(target: Target, faults: Input, keep: Path | None = None) -> Execution:
    """One input as a run of its own, the faults in the scenario (no fork): what
    ``hexhil test`` on the reproducer runs. ``keep``: the trace is kept there."""
    wall0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="hexhil-fuzz-") as tmp:
        trace = Path(tmp) / "run.mcap"
        info = Path(tmp) / "run.info" if target.coverage and _is_elf(target) else None
        probed = target.coverage and target.in_process
        sequences: list[PacketSequence] = []
        undo: list[Callable[[], None]] = []

        def setup(run: Any) -> None:
            if probed:               # after an in-process module's import, before it runs
                undo.append(probe_lines(target))
                line_probes.reset()
            sequences.append(PacketSequence(run.sim.bus.monitor))
            run.sim.bus.monitor = sequences[0]

        try:
            summary = run_input(target, faults, trace, coverage=str(info) if info else None,
                                setup=setup)
        finally:
            for put_back in undo:
                put_back()
        lines = line_features(line_probes.lines()) if probed else set()
        failures, details = judge(target.case, summary, evaluate(target.case, summary, trace))
        features = lines | (elf_lines(info) if info is not None else set()) | (
            sequences[0].pairs if sequences else set())
        if keep is not None:
            shutil.copyfile(trace, keep)
    return Execution(failures, details, frozenset(features), time.perf_counter() - wall0)


def _is_elf(target: Target) -> bool:
    from hexhil.hil.mcu.elf_image import is_arm_elf

    return target.firmware is not None and is_arm_elf(Path(target.firmware))


def probe_lines(target: Target) -> Callable[[], None]:
    """Probes in the functions of ours and of an in-process module's folder (line_probes.py),
    and the profiling clock counting calls (``in_process.counted_profiling_clock``): which
    lines run must not hang on the machine's load (a cycle slower than any before it), or a
    seed would not give one campaign. Returns what puts the wall clock back."""
    roots = [ROOT / "firmware"]
    if target.main_file:
        roots.append(Path(target.main_file).resolve().parent)
    line_probes.install(roots)
    return in_process.counted_profiling_clock()
