"""The C SDK (firmware/c_sdk/, docs/c-firmware.md): C firmware built with ``hexhil sdk
build`` runs in lockstep under ``hexhil run --firmware``. Every program here is compiled
into a tmp folder by the machine's C compiler (or ziglang's, host_tools/c_sdk.py)."""
import json
import os
import shlex
import subprocess
import sys

import pytest

from hexhil.hil.link import served_firmware
from hexhil.hil.link.firmware_process import firmware_env
from hexhil.hil.link.client_conformance import SESSIONS, run_suite
from hexhil.hil.run_result import Ending
from hexhil import c_sdk
from hexhil.trace.reader import Trace
from hexhil.replay import replay_firmware
from hexhil.run_summary import run
from hexhil.trace.reader import info
from hexhil.protocol.errors import UserError
from conftest import ROOT, hexhil_in_process

PROGRAMS = ROOT / "tests" / "c_firmware"
FLAT = str(ROOT / "scenarios" / "flat-tripod.toml")


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """name -> executable of every C program of these tests."""
    out = tmp_path_factory.mktemp("c_firmware")
    progs = {"c_tripod": ([ROOT / "examples" / "c_tripod" / "main.c"], ()),
             "c_client": ([ROOT / "tests" / "link_clients" / "c_client.c"], ()),
             "hal_check": ([PROGRAMS / "hal_check.c"], ()),
             "no_transmitter": ([PROGRAMS / "no_transmitter.c"], ()),
             "crash": ([PROGRAMS / "misbehave.c"], ("-DMODE=1",)),
             "hang": ([PROGRAMS / "misbehave.c"], ("-DMODE=2",)),
             "early_exit": ([PROGRAMS / "misbehave.c"], ("-DMODE=3",)),
             "no_link": ([PROGRAMS / "misbehave.c"], ("-DMODE=4",)),
             "chatty": ([PROGRAMS / "misbehave.c"], ("-DMODE=5",)),
             "polls": ([PROGRAMS / "misbehave.c"], ("-DMODE=6",))}
    return {name: str(c_sdk.build([str(s) for s in srcs], out / name, flags))
            for name, (srcs, flags) in progs.items()}


def test_the_c_tripod_walks_flat_tripod_with_the_same_digest_twice(built):
    first, _ = run(FLAT, firmware=built["c_tripod"])
    second, _ = run(FLAT, firmware=built["c_tripod"])
    assert first["body"]["dx_m"] >= 0.3
    assert first["serial_digest"] == second["serial_digest"]
    assert first["faults"] == {} and first["firmware_runtime"] == "executable"


def test_a_c_firmwares_trace_replays_into_the_same_executable(built, tmp_path):
    trace = tmp_path / "c.mcap"
    run(FLAT, duration_s=1.0, out=str(trace), firmware=built["c_tripod"])
    r = replay_firmware(trace, firmware=built["c_tripod"])
    assert r.identical and r.divergence is None and r.compared_messages > 100
    # a firmware that is not the recorded one diverges
    other = replay_firmware(trace, firmware=built["no_transmitter"])
    assert not other.identical and other.divergence is not None


def test_hexhil_test_judges_the_c_tripod(built, tmp_path):
    case = tmp_path / "c_tripod.toml"
    case.write_text('expect = [\n'
                    '  { name = "walks ahead", kind = "displacement", window_s = [2, 8], '
                    'dx_m = [0.15, 0.4] },\n'
                    '  { name = "no protocol violations", kind = "protocol" }]\n'
                    f'[case]\nscenario = "{FLAT}"\nduration_s = 8\n')

    def judge(firmware):
        return hexhil_in_process("test", case, "--firmware", firmware)

    proc = judge(built["c_tripod"])
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "2 of 2 expectations passed" in proc.stdout
    # the SDK's direction mistakes reach the master check, as the virtual board's do
    proc = judge(built["no_transmitter"])
    row = next(line for line in proc.stdout.splitlines() if "no protocol violations" in line)
    assert proc.returncode == 1 and "tx_while_receiving" in row and row.endswith("FAIL"), row


def test_the_hal_keeps_cubes_promises_in_virtual_time(built):
    s, result = run(FLAT, duration_s=0.5, firmware=built["hal_check"])
    assert result.exit_code == 0 and s["sim_time_s"] == 0.5
    assert result.firmware.timeouts == 1          # servo 99 only


def test_a_firmware_that_never_enables_the_transmitter_times_out_and_is_named(built):
    proc = hexhil_in_process("run", FLAT, "--duration", "1", "--firmware",
                             built["no_transmitter"], "--json")
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    faults = json.loads(lines[-1])["faults"]
    # a 30 ms cycle (10 ms time-out, HAL_Delay(19) + 1) over 1 s: 34 packets lost, 34 time-outs
    assert faults == {"detected_timeouts": 34, "tx_while_receiving": 34}
    assert "faults: detected_timeouts 34, tx_while_receiving 34" in lines


@pytest.mark.parametrize("mode, says", [
    ("crash", "crashed at t=0.2"), ("early_exit", "exited at t=0.2"),
    ("hang", "hang hung: no link message for 2 s of wall time"),
    ("polls", "polls hung: no UART write or read, direction turn or delay for 2 virtual "
              "seconds (since t=0.2")])
def test_a_misbehaving_executable_is_one_line_and_its_trace_is_kept(built, tmp_path, mode,
                                                                    says, monkeypatch):
    monkeypatch.setattr(served_firmware, "HANG_WALL_S", 2.0)
    trace = tmp_path / "run.mcap"
    s, result = run(FLAT, firmware=built[mode], out=str(trace))   # a verdict, not an error
    reason = result.ending.reason
    assert not result.ending.completed and s["ending"]["reason"] == reason
    assert says in reason and "\n" not in reason
    if mode == "crash":
        assert "SIGSEGV" in reason
    kept = info(trace)   # every chunk's CRC checked; the 10 Hz ground truth up to the end
    assert kept["end_s"] >= 0.1 and "/body" in [t["topic"] for t in kept["topics"]]


def test_an_executable_that_exits_before_it_connects_is_one_line(built):
    _, result = run(FLAT, duration_s=0.5, firmware=built["no_link"])
    assert result.ending.kind is Ending.FAILED_TO_START
    assert result.ending.reason.endswith("exited with code 1 before it connected to the "
                                         "link: no board here")


def test_a_firmware_that_prints_a_lot_runs_to_the_end(built):
    s, result = run(FLAT, duration_s=0.5, firmware=built["chatty"])
    assert result.exit_code == 0 and s["sim_time_s"] == 0.5


def test_a_file_that_is_not_executable_is_refused_in_one_line(tmp_path):
    src = ROOT / "examples" / "c_tripod" / "main.c"
    proc = hexhil_in_process("run", FLAT, "--firmware", src)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.strip().splitlines() == [f"hexhil: --firmware {src}: neither a "
                                                "MicroPython main file (.py) nor executable "
                                                "(build a C firmware with `hexhil sdk build "
                                                "main.c -o fw`, or chmod +x)"]


def test_the_first_firmware_of_the_docs_builds_with_the_documented_command_and_runs(tmp_path):
    doc = (ROOT / "docs" / "your-firmware.md").read_text()
    main = tmp_path / "main.c"
    main.write_text(doc.split("```c\n", 1)[1].split("```", 1)[0])
    fw = tmp_path / "fw"
    subprocess.run([sys.executable, "-m", "hexhil.cli", "sdk", "build", str(main), "-o",
                    str(fw)], cwd=tmp_path, check=True, capture_output=True)
    s, result = run(FLAT, duration_s=1.0, firmware=str(fw))
    assert result.exit_code == 0 and s["faults"] == {} and result.firmware.timeouts == 0
    # one answered ping a cycle of 20 ms and the ping's bus time
    assert result.firmware.transactions == result.firmware.cycles >= 45
    # the same source as an F411 ELF on the emulated board: every ping on the line answered
    elf = tmp_path / "fw.elf"
    subprocess.run([sys.executable, "-m", "hexhil.cli", "sdk", "build", "--target",
                    "stm32f411", str(main), "-o", str(elf)], cwd=tmp_path, check=True,
                   capture_output=True)
    s, _ = run(FLAT, duration_s=1.0, firmware=str(elf), out=str(tmp_path / "elf.mcap"))
    assert s["faults"] == {} and s["no_servo_answered"] is None
    with Trace(tmp_path / "elf.mcap") as t:
        replies = [m for _, m in t.decoded(["/serial"]) if m["direction"] == "rx"]
    assert len(replies) >= 45      # one status of servo 1 a 20 ms cycle


def test_firmware_and_python_together_are_refused(built):
    with pytest.raises(UserError, match="brings its own runtime: leave out python"):
        run(FLAT, python="cpython", firmware=built["c_tripod"])


def test_the_link_conformance_suite_passes_against_the_c_client(built):
    env = {k: v for k, v in firmware_env(0).items() if k in ("MICROPYPATH", "PYTHONPATH")}
    results = run_suite([built["c_client"]], env)
    assert [f"{r.name}: {r.detail}" for r in results if not r.passed] == []
    assert len(results) == sum(len(checks) for _, checks in SESSIONS.values())


def test_sdk_flags_build_a_firmware_from_a_users_own_makefile_line(tmp_path):
    proc = hexhil_in_process("sdk", "flags", "--lib-dir", tmp_path / "lib")
    assert proc.returncode == 0, proc.stderr
    flags = dict(ln.split(" += ", 1) for ln in proc.stdout.splitlines())
    assert sorted(flags) == ["CFLAGS", "LDLIBS"]
    fw = tmp_path / "fw"
    cmd = [*c_sdk.compiler(), *shlex.split(flags["CFLAGS"]),
           str(ROOT / "examples" / "c_tripod" / "main.c"), "-o", str(fw),
           *shlex.split(flags["LDLIBS"])]
    subprocess.run(cmd, check=True)
    assert os.access(fw, os.X_OK)


@pytest.mark.parametrize("argv, says", [
    (["sdk", "build", "missing.c", "-o", "fw"], "missing.c: no such file"),
    (["sdk", "build", "README.md", "-o", "fw"], "README.md: not a C source (.c)"),
    (["sdk", "build", "examples/c_tripod/main.c", "-o", "docs"], "is a folder"),
    (["sdk", "build", "tests/c_firmware/misbehave.c", "-o", "/tmp/x"], "does not build"),
])
def test_sdk_build_bad_input_is_one_line_and_exit_2(argv, says):
    proc = hexhil_in_process(*argv)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1 and says in lines[0]


def test_without_a_c_compiler_on_the_path_ziglang_builds_and_the_build_runs(tmp_path,
                                                                            monkeypatch):
    monkeypatch.delenv("CC", raising=False)
    monkeypatch.setattr(c_sdk.shutil, "which", lambda name: None)
    assert c_sdk.compiler() == [sys.executable, "-m", "ziglang", "cc"]
    fw = c_sdk.build([str(PROGRAMS / "hal_check.c")], tmp_path / "hal_check")
    s, result = run(FLAT, duration_s=0.5, firmware=str(fw))
    assert result.exit_code == 0 and s["sim_time_s"] == 0.5
