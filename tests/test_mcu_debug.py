"""--gdb (a GDB client stops at main and in a function, reads its argument; the trace after
it detaches equals the undebugged run's; breakpoints in an exception handler stop it; `next`
range-steps over a line; a fault halts the core as a signal GDB inspects until it detaches)
and --coverage (LCOV from the DWARF line table)."""
import json
import shutil
import socket
import subprocess

import pytest

from hexhil.hil.mcu.coverage import merge
from mcu_elf import MCU, build
from conftest import HEXHIL, ROOT, hexhil_in_process


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


def gdb_session(tmp_path, elf, commands: str):
    """(GDB's stdout, the run's exit status, its stderr) of ``commands`` against ``elf``
    served with --gdb."""
    gdb = shutil.which("gdb-multiarch") or shutil.which("arm-none-eabi-gdb")
    if gdb is None:
        pytest.fail("gdb-multiarch is missing: apt-get install -y gdb-multiarch")
    port = free_port()
    server = subprocess.Popen(run(elf, "--gdb", str(port), "--quiet"), cwd=ROOT,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    script = tmp_path / "g.cmd"
    script.write_text("set pagination off\nset tcp connect-timeout 120\n"
                      f"target remote 127.0.0.1:{port}\n{commands}")
    g = subprocess.run([gdb, "-q", "-batch", "-x", str(script), str(elf)], capture_output=True,
                       text=True, timeout=120)
    _, err = server.communicate(timeout=300)
    return g.stdout + g.stderr, server.returncode, err


def test_gdb_stops_in_the_systick_handler_and_next_steps_over_a_line(tmp_path):
    elf = build(tmp_path, "ping.c", "BAUD_BRR=50", "RAISE_A1=1", opt="-Og")
    src = (MCU / "ping.c").read_text().splitlines()
    line = {text.strip(): i for i, text in enumerate(src, 1)}
    out, code, err = gdb_session(tmp_path, elf, "break ping\ncontinue\nnext\nnext\ndelete\n"
                                 "break SysTick_Handler\ncontinue\nbt 1\ncontinue\n"
                                 "print ticks\ndelete\ndetach\n")
    assert code == 0, err
    assert "Breakpoint 2, SysTick_Handler () at" in out, out
    pkt = line["uint8_t pkt[6] = {0xFF, 0xFF, (uint8_t)id, 2, 1, 0};"]
    assert f"\n{pkt}\t" in out and f"\n{pkt + 1}\t" in out, out     # next: line by line
    ticks = int(out.split("$1 = ")[1].split()[0])
    assert ticks >= 1, out          # the handler ran once between the two stops


def test_a_fault_is_a_signal_with_its_registers_and_gdb_stays_attached(tmp_path):
    elf = build(tmp_path, "faults.c", "FAULT=2")          # a read of nothing (0x60000000)
    out, code, err = gdb_session(tmp_path, elf, "continue\ninfo registers pc\nbt 1\n"
                                 "continue\nprint/x *(unsigned int *)0x08000000\ndetach\n")
    assert "Program received signal SIGSEGV" in out, out
    assert "a read of nothing" in out, out              # the run's line, as target output
    assert "#0  0x" in out and " in main () at " in out, out    # where it faulted
    assert "$1 = 0x20020000" in out, out     # memory still read after it: the initial SP
    assert out.count("Program received signal SIGSEGV") == 2, out   # it cannot go on
    assert code == 1 and "a read of nothing" in err, err


def test_a_failed_assert_stops_in_gdb_as_sigabrt_in_abort(tmp_path):
    from hexhil import c_sdk
    elf = c_sdk.build([str(ROOT / "tests" / "elf_firmware" / "endings.c")],
                      tmp_path / "assert.elf", ("-DEND=END_ASSERT",), "stm32f411")
    out, code, err = gdb_session(tmp_path, elf, "continue\nbt 3\ndetach\n")
    assert "Program received signal SIGABRT" in out, out
    assert "failed an assertion: assert(servos_found == 18)" in out, out
    assert "#0  " in out and "abort" in out.split("#0  ")[1].splitlines()[0], out
    assert "__assert_func" in out, out
    assert code == 1 and "failed an assertion" in err, err


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


def test_coverage_is_of_the_firmwares_own_sources_unless_the_libraries_are_asked_for(
        tmp_path):
    from hexhil import c_sdk
    src = ROOT / "tests" / "elf_firmware" / "endings.c"     # printf: newlib-nano's
    elf = c_sdk.build([str(src)], tmp_path / "endings.elf", ("-DEND=END_NONE",), "stm32f411")
    files = {}
    for name, extra in (("own", ()), ("all", ("--coverage-libraries",))):
        info = tmp_path / f"{name}.info"
        r = subprocess.run(run(elf, "--coverage", str(info), "--quiet", *extra), cwd=ROOT,
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        files[name] = {row[3:] for row in info.read_text().splitlines() if row.startswith("SF:")}
    assert str(src) in files["own"], files["own"]
    assert not [f for f in files["own"] if "newlib" in f or "libgcc" in f], files["own"]
    assert files["own"] < files["all"]
    assert any("/newlib/libc/" in f for f in files["all"]), files["all"]
    assert any("libgcc" in f for f in files["all"]), files["all"]
    bad = hexhil_in_process(*run(elf, "--coverage-libraries")[len(HEXHIL):])
    assert bad.returncode == 2 and "--coverage-libraries needs --coverage" in bad.stderr, bad.stderr
    case = tmp_path / "short.toml"      # hexhil test merges the same way
    case.write_text(f'[case]\nscenario = "{ROOT}/scenarios/flat-tripod.toml"\nduration_s = 0.1'
                    '\n\n[[expect]]\nname = "no firmware exception"\nkind = "no_exception"\n')
    merged = tmp_path / "merged.info"
    r = hexhil_in_process("test", case, "--firmware", elf, "--coverage", merged,
                          "--coverage-libraries")
    assert r.returncode == 0, r.stdout + r.stderr
    assert {row[3:] for row in merged.read_text().splitlines() if row.startswith("SF:")} \
        == files["all"]
    bad = hexhil_in_process("test", case, "--firmware", elf, "--coverage-libraries")
    assert bad.returncode == 2 and "--coverage-libraries needs --coverage" in bad.stderr


def test_hexhil_test_counts_a_fault_as_a_failing_case_and_merges_coverage(tmp_path):
    case = tmp_path / "short.toml"
    case.write_text(f'[case]\nscenario = "{ROOT}/scenarios/flat-tripod.toml"\nduration_s = 0.2\n\n'
                    '[[expect]]\nname = "no firmware exception"\nkind = "no_exception"\n')
    hard = build(tmp_path, "faults.c", "FAULT=1")
    r = hexhil_in_process("test", case, "--firmware", hard)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "faulted: an undefined instruction (UsageFault)" in r.stdout and "FAIL" in r.stdout
    info = tmp_path / "all.info"
    ping = build(tmp_path, "ping.c", "BAUD_BRR=50", "RAISE_A1=1", opt="-O0")
    r = hexhil_in_process("test", case, "--repeat", "2", "--firmware", ping, "--coverage", info)
    assert "coverage of 2 runs" in r.stdout, r.stdout + r.stderr
    line = next(n for n, text in enumerate((MCU / "ping.c").read_text().splitlines(), 1)
                if text.startswith("void SysTick_Handler"))      # 1 kHz
    handler = next(row for row in info.read_text().splitlines()
                   if row.startswith(f"DA:{line},"))
    assert int(handler.split(",")[1]) >= 2 * 190
