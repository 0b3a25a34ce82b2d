"""The hexhil pytest plugin (entry point ``pytest11``: loaded by any pytest in an environment
where hexhil is installed): run a scenario with the firmware from a test, get a typed result,
check it with the expectation kinds of docs/testing.md, and see measured value against limit
when a check fails, with the run's trace (the failure written into it) named in the report
and in ``--junitxml`` as the test's ``trace`` property.

Fixtures: ``hexhil_run`` (a function: scenario, seed, duration, runtime, tactile, firmware,
main, fs, fs_out, allow_failure -> ``FinishedRun``, whose ``result`` is the run's ``RunResult``; a
firmware that does not complete its run fails the test).
Helpers: ``FinishedRun.check(kind, **keys)``, ``assert_within(name, value, low, high)``.
Options: ``--hexhil-runtime RUNTIME`` (default runtime; ``--hexhil-python`` is its alias),
``--hexhil-firmware PATH`` (a firmware of yours for every run, as ``hexhil run --firmware``),
``--hexhil-main FILE``, ``--hexhil-fs DIR`` and ``--hexhil-fs-out DIR`` (a MicroPython ELF's
/flash, as ``--main``, ``--fs`` and ``--fs-out``: each run's into DIR/<test>-<k>/),
``--hexhil-keep DIR`` (copy the trace of every failing test there).
"""
from __future__ import annotations

import dataclasses
import os
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

import pytest

if TYPE_CHECKING:
    from hexhil.hil.run_result import RunResult


@dataclass(frozen=True)
class FinishedRun:
    """A run as a test sees it: the run's ``RunResult`` (what ``Run.run()`` returns), its
    ``hexhil run --json`` view (``summary``, plus ``violations``: what expectations read)
    and its trace."""

    scenario: str
    seed: int
    runtime: str
    result: "RunResult"
    summary: dict[str, Any]
    trace: Path
    case: Any = dataclasses.field(repr=False)        # hexhil.expect.spec.Case
    _record: Callable[[Path], None] = dataclasses.field(repr=False)

    @property
    def body(self) -> dict[str, float]:
        return self.summary["body"]

    @property
    def ending(self) -> dict[str, Any]:
        """How the firmware ended (``hexhil run --json``'s ``ending``: kind, reason, last
        lines, t_s, exit_code)."""
        return self.summary["ending"]

    def check(self, kind: str, name: str | None = None, **keys: Any) -> Any:
        """One expectation (an ``[[expect]]`` table's keys as arguments, ranges as
        ``(low, high)`` or ``{"min": ..}``); returns its ``Outcome``, or fails the test
        with measured value against limit, the failure written into a copy of the trace."""
        from hexhil.expect import case_runs, spec, verdicts

        table = {"name": name or kind, "kind": kind, **keys}
        e = spec.expectation(f"{self.scenario} check", table)
        outcome = verdicts.evaluate(dataclasses.replace(self.case, expectations=(e,)),
                                    self.summary, self.trace)[-1]
        if not outcome.passed:
            slug = "".join(c if c.isalnum() else "-" for c in outcome.name)
            failed = self.trace.with_name(f"{self.trace.stem}-failed-{slug}.mcap")
            case_runs.annotate(self.trace, failed, [outcome], self.summary["sim_time_s"])
            self._record(failed)
            where = f" at t={outcome.t_s:.3f} s" if outcome.t_s is not None else ""
            raise AssertionError(f"{outcome.name}: measured {outcome.measured}; limit "
                                 f"{outcome.limit}{where} (trace: {failed})")
        return outcome


def assert_within(name: str, value: float, low: float | None = None,
                  high: float | None = None, unit: str = "") -> None:
    """Fail with ``name: measured VALUE UNIT; limit [LOW, HIGH]`` unless low <= value <= high."""
    from hexhil.expect.spec import Range

    r = Range(low, high)
    if not r.holds(value):
        raise AssertionError(f"{name}: measured {value:.6g}{' ' + unit if unit else ''}; "
                             f"limit {r}{' ' + unit if unit else ''}")


def pytest_configure(config: pytest.Config) -> None:
    """Under pytest-xdist each worker's runs share the machine with the others'."""
    workers = os.environ.get("PYTEST_XDIST_WORKER_COUNT", "")
    if workers.isdigit():
        from hexhil.hil.link.firmware_process import runs_share_cores
        runs_share_cores(int(workers))


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("hexhil", "hexhil firmware-in-the-loop runs")
    group.addoption("--hexhil-runtime", "--hexhil-python", dest="hexhil_runtime", default=None,
                    metavar="RUNTIME",
                    help="firmware runtime of hexhil_run (default: the scenario's, else "
                         "micropython; cpython-inprocess is faster, same digest)")
    group.addoption("--hexhil-firmware", default=None, metavar="PATH",
                    help="run hexhil_run's scenarios with this firmware instead of ours (a "
                         "MicroPython main file for the virtual board, or an executable)")
    group.addoption("--hexhil-main", default=None, metavar="MAIN.py",
                    help="with a MicroPython ELF as the firmware: lay this file into its "
                         "/flash as main.py (hexhil run --main)")
    group.addoption("--hexhil-fs", default=None, metavar="DIR",
                    help="with a MicroPython ELF: lay DIR's files into its /flash (--fs)")
    group.addoption("--hexhil-fs-out", default=None, metavar="DIR",
                    help="with a MicroPython ELF: write each run's /flash into "
                         "DIR/<test>-<k>/ after it (--fs-out)")
    group.addoption("--hexhil-keep", default=None, metavar="DIR",
                    help="copy the traces of every failing test here")


@pytest.fixture
def hexhil_run(request: pytest.FixtureRequest, tmp_path: Path) -> Callable[..., FinishedRun]:
    """``hexhil_run(scenario, seed=None, duration_s=None, runtime=None, tactile=None,
    firmware=None, main=None, fs=None, fs_out=None, allow_failure=False)``: run a scenario
    file with our firmware (or ``firmware``, else ``--hexhil-firmware``; ``main`` and ``fs``,
    else ``--hexhil-main`` and ``--hexhil-fs``, fill a MicroPython ELF's /flash, and
    ``fs_out``, else ``--hexhil-fs-out``, gets it back after the run), recorded to this
    test's tmp_path. A firmware
    that crashes, hangs, exits early or never starts fails the test with its reason and
    last lines (the trace kept), unless ``allow_failure``: then ``FinishedRun.ending``
    says how it ended and ``check("no_exception")`` judges it."""
    from hexhil.hil import scenario as scenario_mod
    from hexhil.expect import case_runs, spec, verdicts

    traces: list[Path] = []
    request.node.stash[_TRACES] = traces

    def keep(path: Path) -> None:
        traces.append(path)
        _record_trace(request, path)

    def run(scenario: str | Path, seed: int | None = None, duration_s: float | None = None,
            runtime: str | None = None, tactile: bool | None = None,
            firmware: str | Path | None = None, main: str | Path | None = None,
            fs: str | Path | None = None, fs_out: str | Path | None = None,
            allow_failure: bool = False) -> FinishedRun:
        from hexhil.hil.mcu.flash_fs import FlashFiles
        sc = scenario_mod.load_scenario(scenario)
        seed = sc.scenario.seed if seed is None else seed
        duration = duration_s or sc.scenario.duration_s
        runtime = (runtime or request.config.getoption("hexhil_runtime")
                   or sc.firmware.python.value)
        trace = tmp_path / f"{Path(scenario).stem}-seed{seed}-{len(traces)}.mcap"
        firmware = firmware or request.config.getoption("--hexhil-firmware")
        main = main or request.config.getoption("--hexhil-main")
        fs = fs or request.config.getoption("--hexhil-fs")
        if fs_out is None and request.config.getoption("--hexhil-fs-out"):
            fs_out = (Path(request.config.getoption("--hexhil-fs-out"))
                      / f"{case_runs.label_stem(request.node.name)}-{len(traces)}")
        flash = (FlashFiles(*(None if v is None else Path(v) for v in (main, fs, fs_out)))
                 if main or fs or fs_out else None)
        summary, result = case_runs.run_scenario(sc, seed, duration, runtime, tactile, trace,
                                                 firmware=str(firmware) if firmware else None,
                                                 flash_files=flash)
        keep(trace)
        case = spec.Case(name=Path(scenario).stem, path=Path(scenario), scenario=sc, seed=seed,
                         duration_s=duration, tactile=tactile, python=runtime, expectations=(),
                         firmware=str(firmware) if firmware else None, flash_files=flash)
        done = FinishedRun(str(scenario), seed, runtime, result, summary, trace, case, keep)
        ended = verdicts.ending_outcome(case.name, summary)
        if ended is not None and not allow_failure:   # a verdict: the test fails, not errors
            failed = trace.with_name(f"{trace.stem}-failed-firmware.mcap")
            case_runs.annotate(trace, failed, [ended], summary["sim_time_s"])
            keep(failed)
            last = "".join(f"\n  {x}" for x in summary["ending"]["last_lines"])
            raise AssertionError(f"{ended.measured}{last}\n(trace: {failed})")
        return done

    return run


_TRACES = pytest.StashKey[list]()


def _copy(src: Path, dst: Path) -> Path:
    """``src`` copied to ``dst`` as every trace is written (host_tools/trace/target.py); a
    session's ``--hexhil-keep DIR`` replaces a copy an earlier session kept by that name."""
    from hexhil.trace.target import TraceTarget

    dst.parent.mkdir(parents=True, exist_ok=True)
    with open(src, "rb") as f, TraceTarget(dst, overwrite=True) as out:
        shutil.copyfileobj(f, out)
    return dst
def _record_trace(request: pytest.FixtureRequest, path: Path) -> None:
    """The trace's path in ``--junitxml``: a testcase property where the JUnit family has
    them (legacy, xunit1), else (pytest's default xunit2, whose testcase has none, and
    where ``record_property`` warns) a testsuite property ``trace <test id>``."""
    if request.config.getini("junit_family") == "xunit2":
        request.getfixturevalue("record_testsuite_property")(
            f"trace {request.node.nodeid}", str(path))
    else:
        request.node.user_properties.append(("trace", str(path)))


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo) -> Any:
    """A failing test's report names its traces (kept in DIR with --hexhil-keep)."""
    report = yield
    traces = item.stash.get(_TRACES, [])
    if report.when == "call" and report.failed and traces:
        keep_dir = item.config.getoption("--hexhil-keep")
        paths = []
        for t in traces:
            if keep_dir:
                t = _copy(t, Path(keep_dir) / f"{item.name}-{t.name}")
            paths.append(str(t))
        report.sections.append(("hexhil traces", "\n".join(paths)))
    return report
