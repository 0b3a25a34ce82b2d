"""Never hang, never eat the machine: a firmware that floods the link, a wrapper script
whose child holds on, a signal to hexhil's PID alone, a run past its wall-clock or memory
cap; each ends as a verdict or a clean exit within seconds (docs/hardening.md)."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from hexhil.hil.link.firmware_child import FirmwareProcess
from hexhil.hil.link.firmware_process import FirmwareError
from hexhil.hil.run.limits import RunLimits
from hexhil.hil.run_result import Ending
from hexhil import Run, c_sdk
from hexhil.trace.reader import Trace
from hexhil.trace.target import partial_of
from conftest import HEXHIL, ROOT
from ctrl_c import sigint_default

FLAT = ROOT / "scenarios" / "flat-tripod.toml"
BOARD_TRIPOD = ROOT / "examples" / "board_tripod.py"


def _gone(pgid: int) -> bool:
    """No process of group ``pgid`` runs (a zombie waiting for its reaper has ended)."""
    deadline = time.monotonic() + 2.0
    while time.monotonic() < deadline:
        running = []
        for stat in Path("/proc").glob("[0-9]*/stat"):
            try:
                fields = stat.read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[2]) == pgid and fields[0] != "Z":
                running.append(stat)
        if not running:
            return True
        time.sleep(0.05)
    return False


def test_a_c_firmware_that_floods_the_link_is_a_verdict_not_the_kernels_kill(
        tmp_path: Path) -> None:
    fw = c_sdk.build([str(ROOT / "tests" / "c_firmware" / "flood.c")], tmp_path / "flood")
    t0 = time.monotonic()
    with Run(FLAT, firmware=fw, duration_s=3.0) as r:
        result = r.run()
    assert time.monotonic() - t0 < 60
    assert result.ending.kind is Ending.CRASHED, result.ending
    assert "without a request" in result.ending.reason


def test_a_wrapper_that_never_connects_is_ended_with_its_children(tmp_path: Path) -> None:
    pid_file = tmp_path / "pid"
    wrapper = tmp_path / "w.sh"
    wrapper.write_text(f"#!/bin/sh\necho $$ > {pid_file}\nsleep 1000\n")   # no exec
    wrapper.chmod(0o755)
    t0 = time.monotonic()
    with pytest.raises(FirmwareError, match="did not connect within 1 s"):
        FirmwareProcess("executable", connect_timeout_s=1.0, command=[str(wrapper)])
    assert time.monotonic() - t0 < 10
    assert _gone(int(pid_file.read_text()))   # the sleep went with its shell


def _start_run(tmp_path: Path, *extra: str) -> tuple[subprocess.Popen, Path]:
    """``hexhil run`` with a long board firmware run, once its trace is being written."""
    out = tmp_path / "run.mcap"
    proc = subprocess.Popen([*HEXHIL, "run", str(FLAT), "--firmware", str(BOARD_TRIPOD),
                             "--duration", "600", "--out", str(out), "--json", *extra],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True,   # no group signal reaches it
                            preexec_fn=sigint_default)
    partial = partial_of(out)
    deadline = time.monotonic() + 60
    while (not partial.exists() or partial.stat().st_size < 100_000) \
            and time.monotonic() < deadline:
        time.sleep(0.1)
    assert proc.poll() is None, proc.communicate()
    return proc, out


@pytest.mark.parametrize("signum,status", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_signal_to_the_pid_alone_ends_a_run_at_once_with_the_trace_finished(
        tmp_path: Path, signum: int, status: int) -> None:
    proc, out = _start_run(tmp_path)
    t0 = time.monotonic()
    os.kill(proc.pid, signum)
    stdout, stderr = proc.communicate(timeout=60)
    took_s = time.monotonic() - t0
    assert proc.returncode == status, stderr
    assert took_s < 2.0, took_s       # the firmware is ended, not waited for (about 0.1 s)
    assert "Traceback" not in stderr
    assert json.loads(stdout.strip().splitlines()[-1])["interrupted"] is True
    with Trace(out) as t:             # opens only with a summary: the file was finished
        assert sum(1 for _ in t.messages()) > 0


def test_a_run_past_its_wall_clock_cap_ends_as_a_limit_verdict(tmp_path: Path) -> None:
    out = tmp_path / "capped.mcap"
    t0 = time.monotonic()
    proc = subprocess.run([*HEXHIL, "run", str(FLAT), "--firmware", str(BOARD_TRIPOD),
                           "--duration", "600", "--max-wall", "2", "--out", str(out),
                           "--json"], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert time.monotonic() - t0 < 60
    assert proc.returncode == 1, proc.stderr
    s = json.loads(proc.stdout.strip().splitlines()[-1])
    assert s["limit_hit"] == "wall" and s["ending"]["kind"] == "limit", s
    assert "wall-clock cap of 2 s" in s["ending"]["reason"]
    assert s["interrupted"] is False and 0 < s["sim_time_s"] < 600
    assert "Traceback" not in proc.stderr
    assert proc.stderr.strip().splitlines()[-1].startswith("hexhil: the run took more than")
    with Trace(out) as t:
        assert sum(1 for _ in t.messages()) > 0


def test_a_run_past_its_memory_cap_ends_as_a_limit_verdict() -> None:
    with Run(FLAT, firmware=BOARD_TRIPOD, duration_s=600.0,
             limits=RunLimits(max_memory_mb=1.0)) as r:   # below any process's
        result = r.run()
    assert result.limit_hit == "memory"
    assert result.ending.kind is Ending.LIMIT
    assert "memory cap of 1 MiB" in result.ending.reason
    assert result.sim_time_s < 600


def test_a_child_forked_mid_run_ends_the_watch_its_thread_held_a_lock_of() -> None:
    """The bus fuzzer forks a run whose watch thread can hold its event's lock at that
    moment (woken, waiting for the interpreter): the child, with no such thread, must still
    end the run, not wait on that lock for ever (a fuzzed input taken for a hang)."""
    import threading

    from hexhil.hil.run.limits import RunWatch

    watch = RunWatch(RunLimits(), 1.0)
    with watch:
        held, release = threading.Event(), threading.Event()

        def hold() -> None:
            with watch._stop._cond:
                held.set()
                release.wait()

        holder = threading.Thread(target=hold)
        holder.start()
        held.wait()
        pid = os.fork()
        if pid == 0:
            signal.alarm(5)
            watch.__exit__(None, None, None)
            os._exit(0)
        release.set()
        holder.join()
        _, status = os.waitpid(pid, 0)
    assert os.WIFEXITED(status) and os.WEXITSTATUS(status) == 0


@pytest.mark.parametrize("argv", [["--max-wall", "nan"], ["--max-wall", "-1"],
                                  ["--max-memory", "0"], ["--max-memory", "nan"]])
def test_bad_limits_are_one_line_and_exit_2(argv: list[str]) -> None:
    proc = subprocess.run([*HEXHIL, "run", str(FLAT), *argv], cwd=ROOT, capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1 and argv[0] in proc.stderr, proc.stderr


JUNIT_CASE = '''[case]
name = "{name}"
scenario = "{flat}"
duration_s = 1
python = "cpython-inprocess"

[[expect]]
name = "no firmware exception"
kind = "no_exception"

[[expect]]
name = "speed"
kind = "speed"
window_s = [0, 1]
min_m_s = {min_m_s}
'''


@pytest.mark.parametrize("min_m_s,status", [(0, 2), (10, 1)])
def test_a_junit_report_that_cannot_be_written_keeps_the_verdict(
        tmp_path: Path, min_m_s: float, status: int) -> None:
    case = tmp_path / "case.toml"
    case.write_text(JUNIT_CASE.format(name="short", flat=FLAT, min_m_s=min_m_s))
    proc = subprocess.run([*HEXHIL, "test", str(case), "--junit", "/dev/full"], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == status, proc.stdout + proc.stderr
    assert proc.stderr.strip().splitlines()[-1].startswith(
        "hexhil: the JUnit report /dev/full: cannot write")


CHATTY = '''import time
line = "x" * 99
while True:
    for _ in range(100):
        print(line)
    time.sleep_ms(1)
'''


def test_a_chatty_firmwares_prints_are_bounded_and_the_rest_is_reported(tmp_path: Path) -> None:
    from hexhil.hil.link.served_firmware import CONSOLE_TRACE_BYTES

    fw = tmp_path / "chatty.py"
    fw.write_text(CHATTY)                   # 10 kB a virtual millisecond
    out = tmp_path / "chatty.mcap"
    with Run(FLAT, firmware=fw, duration_s=1.0, trace=out) as r:
        result = r.run()
    assert result.ending.completed, result.ending
    assert result.console_dropped_bytes > 5_000_000
    with Trace(out) as t:
        kept = sum(len(msg["text"]) + 1 for _, msg in t.decoded(["/telemetry"])
                   if "text" in msg)
    assert 0.9 * CONSOLE_TRACE_BYTES < kept <= CONSOLE_TRACE_BYTES


BAD_MASTER = '''import time
from machine import Pin, UART

uart = UART(2, baudrate=1000000, timeout=2, timeout_char=1)
direction = Pin("A1", Pin.OUT, value=0)
body = bytes((1, 2, 0x55))                    # instruction 0x55: no AX-12 has it
while True:
    direction.value(1)
    uart.write(b"\\xff\\xff" + body + bytes(((~sum(body)) & 0xFF,)))
    uart.flush()
    direction.value(0)
    time.sleep_ms(20)
'''


def test_a_run_of_your_firmware_counts_the_masters_protocol_mistakes(tmp_path: Path) -> None:
    fw = tmp_path / "bad_master.py"
    fw.write_text(BAD_MASTER)
    out = tmp_path / "bad.mcap"
    proc = subprocess.run([*HEXHIL, "run", str(FLAT), "--firmware", str(fw), "--duration", "1",
                           "--out", str(out), "--json"], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    s = json.loads(proc.stdout.strip().splitlines()[-1])
    assert s["violations"]["counts"]["unsupported_instruction"] >= 10, s["violations"]
    assert "master protocol violations: unsupported_instruction" in proc.stdout
    with Trace(out) as t:
        kinds = {msg["kind"] for _, msg in t.decoded(["/bus/violations"])}
    assert "unsupported_instruction" in kinds


SWALLOWS_EXIT = '''import time
while True:
    try:
        time.sleep_ms(20)
    except:                 # catches the board's SystemExit at the run's end too
        pass
'''


def test_a_firmware_that_swallows_the_end_completes_its_run(tmp_path: Path) -> None:
    fw = tmp_path / "swallows.py"
    fw.write_text(SWALLOWS_EXIT)
    with Run(FLAT, firmware=fw, duration_s=1.0) as r:
        result = r.run()
    assert result.ending.kind is Ending.COMPLETED, result.ending   # hexhil ended it, 2 s on
    assert result.ending.exit_code == -signal.SIGKILL
    assert result.sim_time_s == 1.0


STOPS = '''import time
time.sleep_ms(100)
print("event 2 switch pressed: RF")
while True:
    time.sleep_ms(20)
'''


def test_your_firmwares_own_stop_is_a_safe_stop_and_no_stats_are_made_up(
        tmp_path: Path) -> None:
    fw = tmp_path / "stops.py"
    fw.write_text(STOPS)
    proc = subprocess.run([*HEXHIL, "run", str(FLAT), "--firmware", str(fw), "--duration", "1",
                           "--json"], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    s = json.loads(proc.stdout.strip().splitlines()[-1])
    assert s["stop_reason"] == "switch pressed: RF" and s["stopped_safely"] is True
    first = proc.stdout.splitlines()[0]
    assert "cycles" not in first and "state None" not in first, first
    assert first.endswith("stopped: switch pressed: RF")


def test_hexhil_test_takes_the_caps_and_a_capped_case_fails(tmp_path: Path) -> None:
    case = tmp_path / "long.toml"
    case.write_text(JUNIT_CASE.format(name="long", flat=FLAT, min_m_s=0)
                    .replace("duration_s = 1", "duration_s = 600"))
    proc = subprocess.run([*HEXHIL, "test", str(case), "--max-wall", "2"], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "firmware ending" in proc.stdout and "limit" in proc.stdout
    assert "wall-clock cap of 2 s" in proc.stdout


def test_bus_duration_with_no_master_ends_after_its_seconds_of_waiting() -> None:
    proc = subprocess.run([*HEXHIL, "bus", "--duration", "1"], cwd=ROOT, capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert "served 0 packets" in proc.stdout


def test_a_firmware_in_this_process_is_capped_too_from_any_thread() -> None:
    import threading

    got = []

    def run() -> None:
        with Run(FLAT, runtime="cpython-inprocess", duration_s=600.0,
                 limits=RunLimits(max_wall_s=1.0)) as r:
            got.append(r.run())

    worker = threading.Thread(target=run)   # no signal handler reaches this thread
    worker.start()
    worker.join(timeout=60)
    assert not worker.is_alive() and got
    assert got[0].limit_hit == "wall" and got[0].ending.kind is Ending.LIMIT
    assert 0 < got[0].sim_time_s < 600
