"""How long each side of the link polls for the other's message before it blocks
(hil/link/firmware_process.py ``spin_us``, the hint ``HEXHIL_LINK_SPIN_US`` for the
firmware's HAL, each side's ``PollGate``; the gate itself, firmware/hal/poll_gate.py, is
checked under micropython in tests/micropython/mpy_poll_gate.py): a matter of wall time
only, so the run is the same with or without it; off where the two sides would share one
core; a bad setting is one line."""
from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from hexhil.firmware.hal.sim import Link
from hexhil.hil.link import cores
from hexhil.hil.link.firmware_process import (SPIN_US, Connection, firmware_env, runs_share_cores,
                                       spin_us)
from hexhil.hil.run.lockstep import Simulator
from hexhil.hil.scenario import load_scenario
from hexhil.protocol import sim_link
from conftest import ROOT


def test_polling_or_not_carries_the_same_run(monkeypatch) -> None:
    sc = load_scenario(ROOT / "scenarios" / "flat-tripod.toml")
    got = []
    for us in ("0", "5000"):
        monkeypatch.setenv(sim_link.ENV_SPIN_US, us)
        got.append(Simulator(sc, seed=2).run(2.0, python="micropython"))
    assert got[0].cycles == got[1].cycles > 90
    assert got[0].serial_digest == got[1].serial_digest


@pytest.fixture
def no_quota(monkeypatch, tmp_path):
    """Cores from the affinity alone, whatever cgroup runs these tests."""
    monkeypatch.setattr(cores, "PROC_CGROUP", tmp_path / "none")


def _cgroup(tmp_path: Path, line: str, files: dict[str, str]) -> tuple[Path, Path]:
    """A /proc/self/cgroup holding ``line`` and a cgroup tree of ``files`` (path: text)."""
    tmp_path.mkdir(parents=True, exist_ok=True)
    proc = tmp_path / "proc_cgroup"
    proc.write_text(line + "\n")
    root = tmp_path / "cgroup"
    for name, text in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    return proc, root


def test_a_cgroup_quota_counts_as_cpus(tmp_path) -> None:
    """cgroup v2: the smallest quota along the path; v1 under a container, whose own
    cgroup it sees as the root while /proc names the host's path; no quota set: None."""
    v2 = _cgroup(tmp_path / "v2", "0::/ci.slice/job", {
        "cpu.max": "max 100000\n", "ci.slice/cpu.max": "150000 100000\n",
        "ci.slice/job/cpu.max": "max 100000\n"})
    assert cores.quota_cpus(*v2) == 1.5
    v1 = _cgroup(tmp_path / "v1", "12:memory:/docker/abc\n4:cpu,cpuacct:/docker/abc", {
        "cpu,cpuacct/cpu.cfs_quota_us": "100000\n", "cpu,cpuacct/cpu.cfs_period_us": "100000\n"})
    assert cores.quota_cpus(*v1) == 1.0
    unset = _cgroup(tmp_path / "unset", "1:cpu:/", {
        "cpu/cpu.cfs_quota_us": "-1\n", "cpu/cpu.cfs_period_us": "100000\n"})
    assert cores.quota_cpus(*unset) is None
    assert cores.quota_cpus(tmp_path / "no such file", tmp_path) is None


def test_no_polling_under_a_quota_of_less_than_two_cpus(monkeypatch, tmp_path) -> None:
    """``docker run --cpus=1.5`` on a big host: the affinity says 16, the quota 1.5, and
    two polling processes would spend it and be throttled (docs/link.md)."""
    monkeypatch.delenv(sim_link.ENV_SPIN_US, raising=False)
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(16)))
    proc, root = _cgroup(tmp_path, "0::/", {"cpu.max": "150000 100000\n"})
    monkeypatch.setattr(cores, "PROC_CGROUP", proc)
    monkeypatch.setattr(cores, "CGROUP_ROOT", root)
    assert cores.usable() == 1.5 and spin_us() == 0
    (root / "cpu.max").write_text("200000 100000\n")
    assert cores.usable() == 2.0 and spin_us() == SPIN_US


def test_polling_only_with_a_core_for_each_side(monkeypatch, no_quota) -> None:
    monkeypatch.delenv(sim_link.ENV_SPIN_US, raising=False)
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0})
    assert spin_us() == 0
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1})
    assert spin_us() == SPIN_US > 0
    env = firmware_env(0)   # the firmware's hint, and whose CPU waits its gate reads
    assert env[sim_link.ENV_SPIN_US] == str(SPIN_US)
    assert env[sim_link.ENV_HOST_PID] == str(os.getpid())
    monkeypatch.setenv(sim_link.ENV_SPIN_US, "0")   # the user's setting stands
    assert spin_us() == 0 and firmware_env(0)[sim_link.ENV_SPIN_US] == "0"


def test_runs_sharing_the_cores_do_not_poll(monkeypatch, no_quota) -> None:
    """An executor's workers (host_tools/executor.py) and pytest-xdist's (the plugin) say
    how many runs go side by side."""
    monkeypatch.delenv(sim_link.ENV_SPIN_US, raising=False)
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1, 2, 3})
    runs_share_cores(2)   # a core for each side of two runs
    assert sim_link.ENV_SPIN_US not in os.environ
    runs_share_cores(3)
    assert os.environ[sim_link.ENV_SPIN_US] == "0" and spin_us() == 0
    monkeypatch.setenv(sim_link.ENV_SPIN_US, "50")
    runs_share_cores(3)
    assert spin_us() == 50


@pytest.mark.parametrize("delay_s", [0.0, 0.02])
def test_the_hal_polls_then_blocks_for_a_reply(tmp_path, monkeypatch, delay_s: float) -> None:
    """The reference client (firmware/hal/sim.py) with the hint: a reply that comes while it
    polls, and one that comes long after (it blocks), are read alike."""
    monkeypatch.setenv(sim_link.ENV_SPIN_US, "1000")
    monkeypatch.setenv(sim_link.ENV_HOST_PID, str(os.getpid()))   # this test is the host
    path = str(tmp_path / "link")
    with socket.socket(socket.AF_UNIX) as srv:
        srv.bind(path)
        srv.listen(1)

        def host() -> None:   # the host's own end of the link, not polling (no peer pid)
            conn = Connection(srv.accept()[0])
            conn.batch()
            time.sleep(delay_s)
            conn.reply(1234, b"ok")
            conn.batch()   # until the client closes
            conn.close()
        t = threading.Thread(target=host)
        t.start()
        link = Link(None, path=path)
        assert link.spin_us == 1000
        link.gate.on = True   # as after a look that found the cores free
        link.post(sim_link.OP_SLEEP, b"\0" * 8, 8)
        n = link.call()
        link.close()
        t.join(5)
    assert link.t_us == 1234 and bytes(link.rx[8:n]) == b"ok"


def test_a_bad_setting_is_one_line() -> None:
    env = dict(os.environ, **{sim_link.ENV_SPIN_US: "lots"})
    proc = subprocess.run([sys.executable, "-m", "hexhil.cli", "run",
                           str(ROOT / "scenarios" / "flat-tripod.toml"), "--duration", "0.1"],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and sim_link.ENV_SPIN_US in lines[0] and "Traceback" not in proc.stderr


def test_pytest_xdist_workers_share_the_cores(tmp_path) -> None:
    """The plugin's ``pytest_configure`` in a worker of more than the cores allow."""
    probe = tmp_path / "test_probe.py"
    probe.write_text("import os\n\ndef test_probe():\n"
                     f"    assert os.environ.get({sim_link.ENV_SPIN_US!r}) == '0'\n")
    env = {k: v for k, v in os.environ.items() if k != sim_link.ENV_SPIN_US}
    env["PYTEST_XDIST_WORKER_COUNT"] = str(os.cpu_count() or 1)   # twice the runs' cores
    proc = subprocess.run([sys.executable, "-m", "pytest", str(probe), "-q", "-p",
                           "no:cacheprovider"], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
