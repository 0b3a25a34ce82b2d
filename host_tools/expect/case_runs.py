"""Running expectation cases: one run each (``run_scenario``, the one place a scenario is
run), its outcomes, the trace of a failing case kept with the failures written into it, and
many cases in parallel (host_tools/executor.py: a local process pool or Dask).
"""
from __future__ import annotations

import dataclasses
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Sequence

import can
from mcap.writer import CompressionType, Writer

from hexhil.hil.run.limits import RunLimits
from hexhil.hil.mcu.flash_fs import FlashFiles
from hexhil.hil.link.firmware_process import IN_PROCESS
from hexhil.hil.scenario import Scenario, check_seed
from hexhil.hil.seams import ServoLine
from hexhil import run_summary as run_mod
from hexhil.expect.verdicts import Outcome, evaluate
from hexhil.expect.spec import Case
from hexhil.executor import Executor
from hexhil.progress import Progress
from hexhil.hil.run_result import RunResult
from hexhil.lockstep_run import Run
from hexhil.trace import protobuf as pb
from hexhil.trace import topics
from hexhil.trace.reader import Trace, info
from hexhil.trace.target import TraceTarget
from hexhil.protocol.errors import BadFile, BadValue, UserError

T_EXPECTATIONS = "/expectations"  # foxglove.Log: each failed expectation at its moment


@dataclass(frozen=True)
class BusTiming:
    """Timing-margin settings applied to the simulated bus (hil/servobus/line.py's hooks)."""

    return_delay_us: int | None = None   # servos answer after this, whatever register 5 says
    adapter_latency_us: int = 0          # before the master sees a received byte
    master_baud: int | None = None       # the master UART's true rate (None: the scenario's)

    def overrides(self) -> dict[str, int]:
        """The settings that differ from the scenario's (a run's recorded overrides)."""
        return {k: v for k, v in dataclasses.asdict(self).items()
                if v is not None and not (k == "adapter_latency_us" and v == 0)}

    def apply(self, bus: ServoLine) -> None:
        bus.return_delay_override_us = self.return_delay_us
        bus.rx_latency_us = self.adapter_latency_us
        if self.master_baud is not None:
            bus.set_master_baud(self.master_baud)


@dataclass(frozen=True)
class CaseRun:
    """One run of one case: which, with what seed, and the options the command gave."""

    case: Case
    seed: int
    label: str                            # the case's name, "#k" added for a repeat
    tactile: bool | None = None
    python: str | None = None
    firmware: str | None = None           # the command's --firmware, over the case's
    keep_dir: str | None = None           # keep the trace here when an expectation fails
    keep_all: bool = False                # ... or always (the pytest plugin's fixtures)
    overwrite: bool = False               # replace a kept trace of the same name
    timing: BusTiming = BusTiming()
    scenario: Scenario | None = None      # the case's scenario changed (margin)
    changed: tuple[tuple[str, float], ...] = ()  # ... and what was changed in it (overrides)
    coverage: str | None = None           # an ELF's LCOV to this file (hexhil test --coverage)
    limits: RunLimits | None = None       # the run's caps (hil/run/limits.py; None: defaults)
    flash_files: FlashFiles | None = None  # --main/--fs/--fs-out over the case's, each
    coverage_libraries: bool = False      # ... counting the toolchain's libraries too
    main_file: str | None = None          # a module's main(board) in process, not ours
    masked_limit_s: float | None = None   # an ELF's masked-spin limit (None: the default)


@dataclass(frozen=True)
class CaseResult:
    label: str
    seed: int
    outcomes: tuple[Outcome, ...]
    summary: dict[str, Any]
    trace: str | None                     # the kept trace, if one was kept

    @property
    def passed(self) -> bool:
        return all(o.passed for o in self.outcomes)


class _Sender:
    """A host node that puts the case's CAN frames on the bus at their times."""

    period_us = 1_000

    def __init__(self, run: Run, sends: Sequence[tuple[int, int, bytes]]) -> None:
        self.run, self.sends = run, list(sends)

    def tick(self, t_us: int) -> None:
        while self.sends and self.sends[0][0] <= t_us:
            _, arb_id, data = self.sends.pop(0)
            self.run.send_can(can.Message(arbitration_id=arb_id, data=data,
                                          is_extended_id=False))


def run_scenario(scenario: Scenario, seed: int, duration_s: float, python: str,
                 tactile: bool | None, trace: Path, timing: BusTiming = BusTiming(),
                 sends: Sequence[tuple[int, int, bytes]] = (), firmware: str | None = None,
                 changed: dict[str, Any] | None = None, coverage: str | None = None,
                 limits: RunLimits | None = None,
                 flash_files: FlashFiles | None = None,
                 coverage_libraries: bool = False, masked_limit_s: float | None = None,
                 wrap: Callable[[Run, Any], Any] | None = None, main: Any = None,
                 master_check: bool = True, setup: Callable[[Run], None] | None = None
                 ) -> tuple[dict[str, Any], RunResult]:
    """Run a checked hexapod scenario with our firmware (or ``firmware``, a MicroPython main
    file or an executable: ``hexhil run --firmware``) through the one run path
    (host_tools/lockstep_run.py ``Run``), recorded to ``trace`` with the master's protocol check
    on; returns ``hexhil run --json``'s summary plus ``violations``, and the ``RunResult``.
    Every case and margin run goes through here; ``timing`` and ``changed`` (a scenario key
    changed, e.g. ``faults.bit_error_rate``) are recorded as the run's overrides. In
    process, ``wrap(run, exchange)`` sees every exchange of the link and ``main`` is the
    firmware run (the bus fuzzer: host_tools/bus_fuzz/); ``master_check=False`` leaves the
    master check out (a quarter of a profiled in-process run) where no expectation reads it;
    ``setup(run)`` is called once the run is built (the fuzzer puts its packet sequence on
    the bus's monitor)."""
    run = Run(scenario, seed=seed, runtime=None if firmware else python,
              duration_s=duration_s, tactile=tactile, trace=trace, firmware=firmware,
              overrides={**timing.overrides(), **(changed or {})}, coverage=coverage,
              limits=limits, flash_files=flash_files, coverage_libraries=coverage_libraries,
              masked_limit_s=masked_limit_s)
    try:
        if master_check:
            run.watch_master()
        sim = run.sim
        timing.apply(sim.bus)
        if sends:
            run.add_node(_Sender(run, sends))
        if setup is not None:
            setup(run)
    except BaseException:
        run.close()
        raise
    result = run.run(None if wrap is None else lambda exchange: wrap(run, exchange), main)
    return run_mod.summary(run.scenario, seed, result, str(trace), run.what_ran()), result


def run_case(job: CaseRun) -> CaseResult:
    """Run one case, evaluate it, keep its trace if asked; picklable for worker processes."""
    case = job.case
    tactile = job.tactile if job.tactile is not None else case.tactile
    kept = None
    with tempfile.TemporaryDirectory(prefix="hexhil-test-") as tmp:
        trace = Path(tmp) / "run.mcap"
        main = None
        if job.main_file is not None:
            from hexhil.in_process import load_main

            main = load_main(job.main_file)
        flash = job.flash_files.over(case.flash_files) if job.flash_files else case.flash_files
        if flash is not None and flash.out is not None:   # one folder a run
            flash = dataclasses.replace(flash, out=flash.out / label_stem(job.label))
        summary, _ = run_scenario(job.scenario or case.scenario, job.seed, case.duration_s,
                                  IN_PROCESS if main else job.python or case.python, tactile,
                                  trace, job.timing, case.sends, job.firmware or case.firmware,
                                  dict(job.changed), job.coverage, job.limits, flash,
                                  job.coverage_libraries,
                                  job.masked_limit_s if job.masked_limit_s is not None
                                  else case.masked_limit_s, main=main)
        outcomes = tuple(evaluate(case, summary, trace))
        failed = [o for o in outcomes if not o.passed]
        if job.keep_dir is not None and (failed or job.keep_all):
            kept = keep(trace, job.keep_dir, job.label, failed, summary["sim_time_s"],
                        job.overwrite)
    summary = {k: v for k, v in summary.items() if k != "trace"}
    return CaseResult(job.label, job.seed, outcomes, summary, kept)


def evaluate_recorded(case: Case, trace: Path, keep_dir: str | None = None,
                      overwrite: bool = False) -> CaseResult:
    """``case``'s expectations on a run recorded elsewhere, nothing run: a real board in
    real time (``hexhil bus --world SCENARIO --port DEVICE --out RUN.mcap``), or any trace.
    The run's length is the trace's; a failing case's copy goes to ``keep_dir``."""
    try:
        about = info(trace)
    except UserError:   # the reader's own line (its kinds are OSError and ValueError too)
        raise
    except (OSError, ValueError) as exc:
        raise BadValue(f"trace {trace}: not a readable hexhil trace ({exc})",
                       params=("trace",)) from None
    end_s = about["end_s"]
    linked = about["metadata"].get("command") != "bus"   # hexhil bus --world: no link
    summary = {"sim_time_s": end_s, "firmware_link": linked}
    outcomes = tuple(evaluate(case, summary, trace))
    failed = [o for o in outcomes if not o.passed]
    kept = (keep(trace, keep_dir, case.name, failed, end_s, overwrite)
            if keep_dir and failed else None)
    return CaseResult(case.name, case.seed, outcomes, summary, kept)


def label_stem(label: str) -> str:
    """The case run ``label`` as a file or folder name (its kept trace, its /flash)."""
    return label.replace("/", "_").replace("#", "-")


def kept_path(keep_dir: str, label: str) -> Path:
    """Where ``--keep-traces DIR`` keeps the trace of the case run ``label``."""
    return Path(keep_dir) / (label_stem(label) + ".mcap")


def keep(trace: Path, keep_dir: str, label: str, failed: Sequence[Outcome],
         end_s: float, overwrite: bool = False) -> str:
    """``trace`` copied to ``keep_dir/<label>.mcap`` with ``failed`` written into it."""
    try:
        Path(keep_dir).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BadFile(f"keep_dir {keep_dir}: cannot make the folder "
                      f"({exc.strerror})", params=("keep_dir",)) from None
    kept = kept_path(keep_dir, label)
    annotate(trace, kept, failed, end_s, overwrite)
    return str(kept)


def annotate(src: Path, dst: Path, failed: Sequence[Outcome], end_s: float,
             overwrite: bool = False) -> None:
    """Copy a trace and add each failed expectation as a ``foxglove.Log`` (ERROR) on
    ``/expectations`` at the moment it failed (the run's end when it has none), so a viewer
    opened at that message sees the robot when it went wrong. Written as every trace is
    (host_tools/trace/target.py: an existing ``dst`` refused unless ``overwrite``)."""
    with Trace(src) as tr, TraceTarget(dst, overwrite) as f:
        w = Writer(f, compression=CompressionType.ZSTD)
        w.start(profile=topics.PROFILE, library=tr.header.library)
        schema_ids = {sid: w.register_schema(s.name, s.encoding, s.data)
                      for sid, s in tr.schemas.items()}
        channel_ids = {cid: w.register_channel(c.topic, c.message_encoding,
                                               schema_ids.get(c.schema_id, 0), c.metadata)
                       for cid, c in tr.channels.items()}
        log_schema = w.register_schema("foxglove.Log", "protobuf",
                                       pb.descriptor_set("foxglove.Log"))
        log_channel = w.register_channel(T_EXPECTATIONS, "protobuf", log_schema)
        notes = []
        for o in failed:
            t_ns = int(round((o.t_s if o.t_s is not None else end_s) * 1e9))
            msg = pb.Log(level=pb.Log.ERROR, name=o.name,
                         message=f"{o.name} ({o.kind}) FAILED: measured {o.measured}; "
                                 f"limit {o.limit}")
            msg.timestamp.FromNanoseconds(t_ns)
            notes.append((t_ns, msg.SerializeToString()))
        notes.sort()
        for m in tr.messages():
            while notes and notes[0][0] <= m.log_time_ns:
                t_ns, data = notes.pop(0)
                w.add_message(log_channel, t_ns, data, t_ns)
            w.add_message(channel_ids[m.channel_id], m.log_time_ns, m.data, m.log_time_ns)
        for t_ns, data in notes:
            w.add_message(log_channel, t_ns, data, t_ns)
        metadata = tr.metadata()
        metadata["failed_expectations"] = ", ".join(o.name for o in failed)
        w.add_metadata(topics.METADATA_NAME, metadata)
        w.finish()


def jobs_for(cases: Sequence[Case], repeat: int = 1, **options: Any) -> list[CaseRun]:
    """Each case ``repeat`` times: repeat k runs with the case's seed + k."""
    out = []
    for case in cases:
        check_seed(case.seed + repeat - 1, f"{case.name}: the last repeat's seed ({case.seed} + "
                                           f"{repeat - 1})")
        for k in range(repeat):
            label = case.name if repeat == 1 else f"{case.name}#{k}"
            out.append(CaseRun(case, case.seed + k, label, **options))
    return out


def run_all(jobs: Sequence[CaseRun], workers: int = 1, scheduler: str | None = None,
            progress: Progress | None = None) -> list[CaseResult]:
    """Every job, in parallel when ``workers`` > 1 or on a Dask ``scheduler``; results in
    job order, each one done reported to ``progress``."""
    return Executor(workers, scheduler, progress=progress).map(run_case, list(jobs), "cases")
