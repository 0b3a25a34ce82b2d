"""The bus fuzzer (docs/fuzzing.md) as users run it: ``hexhil fuzz`` on flat-tripod, a 2 s
window after boot, our firmware in process on the fork server, a campaign of the CLI's
default length (200 runs) on two servers (``--jobs 2``), with the default guidance (lines
and packet sequences) and with packets only. The wall rate depends on the machine's load
(in each note); the CPU an execution takes (the servers' and their children's,
``RUSAGE_CHILDREN``, boots included) less so, and a forked child's alone
(``Report.child_cpu_s``) is the window's cost without the boots."""
from __future__ import annotations

import os
import resource
from dataclasses import replace
from pathlib import Path

from bench import Row
from hexhil.bus_fuzz import campaign

ROOT = Path(__file__).resolve().parent.parent
RUNS = 200        # the CLI's default: the servers' boots weigh as in a user's campaign
JOBS = 2


def _campaign(settings: campaign.Settings) -> tuple[campaign.Report, float, str]:
    """The campaign, its servers' and children's CPU seconds, and the 1-minute load average
    before it (the machine's other work) and after (its own two servers in it)."""
    load0 = os.getloadavg()[0]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    report = campaign.fuzz(settings)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu_s = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    return report, cpu_s, f"{load0:.1f} before, {os.getloadavg()[0]:.1f} after"


def run() -> list[Row]:
    base = campaign.Settings(expect=str(ROOT / "examples" / "fuzz-flat-tripod.toml"),
                             scenario=str(ROOT / "scenarios" / "flat-tripod.toml"),
                             runs=RUNS, seed=1, jobs=JOBS)
    rows = []
    for label, settings in ((f"lines and packets, --jobs {JOBS}", base),
                            (f"packets only, --jobs {JOBS}", replace(base, coverage=False))):
        report, cpu_s, load = _campaign(settings)
        done = report.executions + report.shrink_executions
        rows.append(Row(f"fuzz: executions a second ({label})", report.rate, "exec/s", "20",
                        f"flat-tripod, 2 s window, {report.executions} runs and "
                        f"{report.shrink_executions} shrinking in {report.wall_s:.1f} s wall, "
                        f"{len(report.findings)} findings; load {load}"))
        rows.append(Row(f"fuzz: CPU an execution ({label})", 1e3 * cpu_s / done, "ms", "100",
                        f"servers and forks, boots included, {done} executions "
                        f"(20/s on 2 cores: 100); load {load}"))
        rows.append(Row(f"fuzz: CPU a forked child ({label})",
                        1e3 * report.child_cpu_s / report.executions, "ms", "",
                        f"one execution's 2 s window, exit included, {report.executions} "
                        f"executions; load {load}"))
    return rows
