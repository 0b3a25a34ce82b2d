"""How many CPUs this process may keep busy: the link polls only where each side of a run
has one (hil/link/firmware_process.py ``spin_us``), and the recorder forks its encoding
child only beside a spare one (host_tools/trace/windows.py ``encode_in_for``).

Two things narrow the machine's cores: the affinity (``taskset``) and the cgroup's CPU
quota (``docker run --cpus=1``, a CI runner's limit). A quota is not a core count: under
one CPU's quota on a 16-core host the affinity still says 16, and two polling processes
each spin on a core of their own until the quota is spent and the kernel throttles the
group for the rest of the period (a run 30 % slower under ``--cpus=1``). So the
quota counts too: quota / period CPUs, the smallest along the cgroup's path (a limit set
on a parent holds for its children), in cgroup v2's ``cpu.max`` and v1's
``cpu.cfs_quota_us`` / ``cpu.cfs_period_us``. Whatever cannot be read counts as no limit.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Callable

PROC_CGROUP = Path("/proc/self/cgroup")
CGROUP_ROOT = Path("/sys/fs/cgroup")


def usable() -> float:
    """The CPUs this process may use at once: its affinity's count, or fewer where its
    cgroup's quota allows fewer (a fraction where the quota is one)."""
    try:
        cores: float = len(os.sched_getaffinity(0))
    except AttributeError:   # no affinity on this OS
        cores = os.cpu_count() or 1
    quota = quota_cpus()
    return cores if quota is None else min(cores, quota)


def quota_cpus(proc_cgroup: Path | None = None, root: Path | None = None) -> float | None:
    """The CPU quota of this process's cgroup in CPUs (1.5 for ``--cpus=1.5``), or None
    where none is set or none can be read (``proc_cgroup`` and ``root``: where to read,
    this process's by default)."""
    root = CGROUP_ROOT if root is None else root
    try:
        lines = (PROC_CGROUP if proc_cgroup is None else proc_cgroup).read_text().splitlines()
    except OSError:
        return None
    found: list[float] = []
    for line in lines:   # "hierarchy:controllers:path"; cgroup v2's is "0::path"
        parts = line.split(":", 2)
        if len(parts) != 3:
            continue
        _, controllers, path = parts
        if controllers == "":
            found += _limits(root, ("",), path, _v2)
        elif "cpu" in controllers.split(","):
            found += _limits(root, (controllers, "cpu", "cpu,cpuacct"), path, _v1)
    return min(found) if found else None


def _limits(root: Path, mounts: tuple[str, ...], path: str,
            read: Callable[[Path], float | None]) -> list[float]:
    """The quotas set on ``path`` and its parents, under the first mount that holds it.
    Inside a container the path may name the host's cgroup, which the container sees as
    its root: the parents that exist are read."""
    for mount in dict.fromkeys(mounts):
        base = root / mount if mount else root
        if not base.is_dir():
            continue
        out = []
        here = Path("/" + path.strip("/"))
        for d in (here, *here.parents):
            q = read(base / str(d).lstrip("/"))
            if q is not None:
                out.append(q)
        return out
    return []


def _v2(d: Path) -> float | None:
    try:
        quota, period = (d / "cpu.max").read_text().split()
        return None if quota == "max" else int(quota) / int(period)
    except (OSError, ValueError):
        return None


def _v1(d: Path) -> float | None:
    try:
        quota = int((d / "cpu.cfs_quota_us").read_text())
        period = int((d / "cpu.cfs_period_us").read_text())
    except (OSError, ValueError):
        return None
    return None if quota <= 0 or period <= 0 else quota / period
