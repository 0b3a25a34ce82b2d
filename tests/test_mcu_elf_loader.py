"""Hostile ELFs given to --firmware: one line and exit 2 each, before anything runs; a
HardFault ends the run (exit 1, the firmware's verdict) in one line naming the PC and the
function, the trace kept."""
import subprocess

import pytest

from hexhil.hil.mcu.elf_image import load_elf
from hexhil.trace.reader import Trace
from mcu_elf import build
from hexhil.protocol.errors import UserError
from conftest import HEXHIL, ROOT, hexhil_in_process


def hexhil_run(elf, *extra):
    return hexhil_in_process("run", "scenarios/flat-tripod.toml", "--firmware", elf,
                             "--duration", "0.1", "--quiet", *extra)   # the verdict alone


def one_line(r, status=2):
    """The one line on stderr of a run that exits ``status``: 2, bad input to hexhil (a
    hostile ELF); 1, a verdict on the firmware (a fault: the run's ending)."""
    assert r.returncode == status, r.stderr
    assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    return r.stderr.strip()


def patched(tmp_path, elf, offset, data, name):
    raw = bytearray(elf.read_bytes())
    raw[offset:offset + len(data)] = data
    out = tmp_path / name
    out.write_bytes(bytes(raw))
    return out


def test_hostile_elfs_are_one_line_each(tmp_path):
    good = build(tmp_path, "ping.c", "BAUD_BRR=50", "RAISE_A1=1")
    vectors = next(s for s in load_elf(good).segments if s.addr == 0x08000000)
    at = good.read_bytes().find(vectors.data[:16])
    regs = tmp_path / "regs.c"          # a section linked over USART2's registers
    regs.write_text('__attribute__((section(".regs"))) const unsigned over_usart2 = 1;\n')
    cases = {
        "truncated": (tmp_path / "cut.elf", "truncated"),
        "riscv": (patched(tmp_path, good, 18, (243).to_bytes(2, "little"), "rv.elf"),
                  "EM_RISCV"),
        "no vectors": (patched(tmp_path, good, at, b"\0" * 8, "novec.elf"),
                       "reset vector 0x00000000"),
        "reset in RAM": (patched(tmp_path, good, at + 4, (0x20000101).to_bytes(4, "little"),
                                 "ramreset.elf"), "not a Thumb address in flash"),
        "over USART2": (build(tmp_path, "ping.c", "BAUD_BRR=50", "RAISE_A1=1", extra=(str(regs),),
                              cflags=("-Wl,--section-start=.regs=0x40004400",
                                      "-Wl,--require-defined=over_usart2")),
                        "0x40004400 lies outside flash"),
    }
    (tmp_path / "cut.elf").write_bytes(good.read_bytes()[:600])
    for what, (elf, words) in cases.items():
        line = one_line(hexhil_run(elf))
        assert line.startswith("hexhil: --firmware ") and words in line, (what, line)


def test_a_hardfault_is_one_line_with_pc_and_function_and_the_trace_is_kept(tmp_path):
    trace = tmp_path / "t.mcap"
    line = one_line(hexhil_run(build(tmp_path, "faults.c", "FAULT=1"), "--out", str(trace)), 1)
    assert "an undefined instruction (UsageFault) at PC 0x080" in line
    assert "in explode (t=0.0" in line
    with Trace(trace) as t:
        assert "/link" in t.topics()


@pytest.mark.parametrize("fault, words", [
    (2, "a read of nothing at PC 0x080"), (3, "a stack overflow")])
def test_access_to_nothing_and_stack_overflow(tmp_path, fault, words):
    line = one_line(hexhil_run(build(tmp_path, "faults.c", f"FAULT={fault}")), 1)
    assert words in line and " in " in line, line


def test_the_loader_refuses_without_a_traceback(tmp_path):
    bad = tmp_path / "x.elf"
    bad.write_bytes(b"\x7fELF\x01\x01\x01" + bytes(200))
    with pytest.raises(UserError):
        load_elf(bad)


def test_the_trace_is_the_same_bytes_twice_replay_is_identical_a_changed_elf_diverges(tmp_path):
    elf = build(tmp_path, "ping.c", "BAUD_BRR=50", "RAISE_A1=1")
    trace = tmp_path / "t.mcap"
    r = hexhil_run(elf, "--out", str(trace))
    assert r.returncode == 0, r.stderr
    again = tmp_path / "again.mcap"
    assert hexhil_run(elf, "--out", str(again)).returncode == 0
    assert again.read_bytes() == trace.read_bytes()      # the same ELF, scenario, seed
    replay = [*HEXHIL, "replay", str(trace), "--firmware"]
    same = subprocess.run(replay + [str(elf)], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)
    assert same.returncode == 0 and same.stdout.startswith("identical:"), same.stdout + same.stderr
    quiet = build(tmp_path, "ping.c", "BAUD_BRR=50", "RAISE_A1=0")   # never raises PA1
    changed = subprocess.run(replay + [str(quiet)], cwd=ROOT, capture_output=True, text=True,
                             timeout=300)
    assert "DIVERGED at t=0.0" in changed.stdout, changed.stdout + changed.stderr
