"""The bus fuzzer (docs/fuzzing.md): executions a second of a campaign on flat-tripod, a
2 s window after boot, our firmware in process on the fork server; with and without line
coverage, on one server and on two. The wall rate depends on the machine's load; the CPU
an execution takes (the servers' and their children's, ``RUSAGE_CHILDREN``) less so, and
a forked child's alone (``Report.child_cpu_s``) is the window's cost without the boots."""
from __future__ import annotations

import resource
from dataclasses import replace
from pathlib import Path

from bench import Row
from host_tools.bus_fuzz import campaign

CASE = Path(__file__).resolve().parent.parent / "examples" / "fuzz-flat-tripod.toml"
RUNS = 48


def _campaign(settings: campaign.Settings) -> tuple[campaign.Report, float]:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    report = campaign.fuzz(settings)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu_s = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    return report, cpu_s


def run() -> list[Row]:
    base = campaign.Settings(expect=str(CASE), runs=RUNS, seed=1)
    rows = []
    for label, settings in (("lines and packets", base),
                            ("packets only", replace(base, coverage=False)),
                            ("packets only, --jobs 2", replace(base, coverage=False, jobs=2))):
        report, cpu_s = _campaign(settings)
        rows.append(Row(f"fuzz: executions a second ({label})", report.rate, "exec/s", "20",
                        f"flat-tripod, 2 s window, {report.executions} runs and "
                        f"{report.shrink_executions} shrinking, {report.wall_s:.1f} s wall, "
                        f"{len(report.findings)} findings"))
        done = report.executions + report.shrink_executions
        rows.append(Row(f"fuzz: CPU an execution ({label})", 1e3 * cpu_s / done, "ms", "",
                        f"servers and forks, boots included, {done} executions"))
        rows.append(Row(f"fuzz: CPU a forked child ({label})",
                        1e3 * report.child_cpu_s / report.executions, "ms", "100",
                        "one execution's 2 s window, exit included (20/s on 2 cores: 100)"))
    return rows
