"""--gdb (a GDB client stops at main and in a function, reads its argument; the trace after
it detaches equals the undebugged run's) and --coverage (LCOV from the DWARF line table)."""
import json
import shutil
import socket
import subprocess
from pathlib import Path

import pytest

from hil.mcu.coverage import merge
from mcu_elf import MCU, build
from conftest import HEXHIL, hexhil

ROOT = Path(__file__).resolve().parent.parent


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def run(elf, *extra):
    return [*HEXHIL, "run", "scenarios/flat-tripod.toml", "--firmware", str(elf),
            "--duration", "0.3", "--json", *extra]


def test_gdb_stops_at_main_and_in_ping_and_the_trace_is_unchanged(tmp_path):
    gdb = shutil.which("gdb-multiarch") or shutil.which("arm-none-eabi-gdb")
    if gdb is None:
        pytest.fail("gdb-multiarch is missing: apt-get install -y gdb-multiarch")
    elf = build(tmp_path, "ping.c", "BAUD_BRR=50", "RAISE_A1=1", opt="-Og")
    plain = subprocess.run(run(elf), cwd=ROOT, capture_output=True, text=True, timeout=300)
    port = free_port()
    server = subprocess.Popen(run(elf, "--gdb", str(port)), cwd=ROOT, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True)
    script = tmp_path / "g.cmd"      # GDB retries the connection until the run listens
    script.write_text(f"set pagination off\nset tcp connect-timeout 120\ntarget remote 127.0.0.1:{port}\nbreak main\n"
                      "continue\ninfo registers pc\nbreak ping\ncontinue\ncontinue\n"
                      "print id\nbt 1\ndelete\ndetach\n")
    g = subprocess.run([gdb, "-q", "-batch", "-x", str(script), str(elf)], capture_output=True,
                       text=True, timeout=120)
    out, err = server.communicate(timeout=300)
    assert server.returncode == 0, err
    assert "Breakpoint 1, main () at" in g.stdout, g.stdout + g.stderr
    assert "$1 = 2" in g.stdout, g.stdout        # the second ping: servo 2
    debugged = json.loads(out.strip().splitlines()[-1])
    assert debugged["serial_digest"] == json.loads(plain.stdout.strip().splitlines()[-1])[
        "serial_digest"]


def test_lcov_names_source_lines_with_counts_and_zero_for_lines_never_run(tmp_path):
    elf = build(tmp_path, "ping.c", "BAUD_BRR=50", "RAISE_A1=1", opt="-O0")
    info = tmp_path / "ping.info"
    r = subprocess.run(run(elf, "--coverage", str(info)), cwd=ROOT, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    text = info.read_text()
    records = {}
    for block in text.split("end_of_record")[:-1]:
        rows = block.strip().splitlines()
        name = next(x[3:] for x in rows if x.startswith("SF:"))
        records[name] = {int(x[3:].split(",")[0]): int(x.split(",")[1])
                         for x in rows if x.startswith("DA:")}
    ping = records[str(elf.parent.parent / "tests" / "mcu" / "ping.c")] \
        if str(elf.parent.parent / "tests" / "mcu" / "ping.c") in records else \
        next(v for k, v in records.items() if k.endswith("tests/mcu/ping.c"))
    src = (ROOT / "tests" / "mcu" / "ping.c").read_text().splitlines()
    line = {text.strip(): i + 1 for i, text in enumerate(src)}
    assert ping[line["for (int id = 1; id <= 18; id++) n += ping(id);"]] >= 18
    assert ping[line["void SysTick_Handler(void) { ticks++; }"]] >= 290   # 1 kHz for 0.3 s
    # the console line is printed after 1 s of WFI: never reached in 0.3 s
    assert ping[line["console_puts(line);"]] == 0
    assert merge([text, text]).count("DA:") == text.count("DA:")


def test_hexhil_test_counts_a_fault_as_a_failing_case_and_merges_coverage(tmp_path):
    case = tmp_path / "short.toml"
    case.write_text(f'[case]\nscenario = "{ROOT}/scenarios/flat-tripod.toml"\nduration_s = 0.2\n\n'
                    '[[expect]]\nname = "no firmware exception"\nkind = "no_exception"\n')
    hard = build(tmp_path, "faults.c", "FAULT=1")
    r = hexhil("test", str(case), "--firmware", str(hard), timeout=300)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "faulted: an undefined instruction (UsageFault)" in r.stdout and "FAIL" in r.stdout
    info = tmp_path / "all.info"
    ping = build(tmp_path, "ping.c", "BAUD_BRR=50", "RAISE_A1=1", opt="-O0")
    r = hexhil("test", case, "--repeat", "2", "--firmware", ping, "--coverage", info)
    assert "coverage of 2 runs" in r.stdout, r.stdout + r.stderr
    line = next(n for n, text in enumerate((MCU / "ping.c").read_text().splitlines(), 1)
                if text.startswith("void SysTick_Handler"))      # 1 kHz
    handler = next(row for row in info.read_text().splitlines()
                   if row.startswith(f"DA:{line},"))
    assert int(handler.split(",")[1]) >= 2 * 190
