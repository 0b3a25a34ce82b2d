"""Building for the board: ``hexhil sdk build --target stm32f411`` makes an F411
ELF (Thumb-2, hard float, newlib-nano) from the same main.c that builds for the host, with
the SDK's own startup file, linker script and register-level HAL; compiler flags pass
through; ``hexhil sdk flags --target stm32f411`` serves a user's Makefile; a missing
toolchain is one line. What the ELFs do when they run is tests/test_elf_firmware.py."""
import os
import shlex
import subprocess
from pathlib import Path

import pytest
from elftools.elf.elffile import ELFFile

from hexhil import c_sdk
from hexhil.protocol.errors import UserError
from conftest import ROOT, hexhil as hexhil_process, hexhil_in_process as hexhil

TRIPOD = ROOT / "examples" / "c_tripod" / "main.c"
ELF_FW = ROOT / "tests" / "elf_firmware"
FLASH = range(0x08000000, 0x08000000 + 512 * 1024)
SRAM = range(0x20000000, 0x20000000 + 128 * 1024)
EF_ARM_ABI_FLOAT_HARD = 0x400


def layout(path: Path) -> dict:
    """What a flash programmer and the core see of an ELF."""
    with open(path, "rb") as f:
        elf = ELFFile(f)
        symbols = {s.name: s["st_value"] for s in elf.get_section_by_name(".symtab")
                   .iter_symbols() if s.name}
        sections = {s.name: (s["sh_addr"], s["sh_size"]) for s in elf.iter_sections()
                    if s["sh_flags"] & 0x2}   # SHF_ALLOC
        vectors = elf.get_section_by_name(".isr_vector").data()
        attrs = subprocess.run(["arm-none-eabi-readelf", "-A", str(path)], capture_output=True,
                               text=True, check=True).stdout
        return {"machine": elf["e_machine"], "class": elf.elfclass, "flags": elf["e_flags"],
                "entry": elf["e_entry"], "symbols": symbols, "sections": sections,
                "vector": [int.from_bytes(vectors[i:i + 4], "little")
                           for i in range(0, len(vectors), 4)],
                "attributes": attrs, "has_dwarf": elf.has_dwarf_info()}


@pytest.fixture(scope="module")
def tripod_elf(tmp_path_factory):
    out = tmp_path_factory.mktemp("elf") / "c_tripod.elf"
    proc = hexhil("sdk", "build", "--target", "stm32f411", str(TRIPOD), "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == str(out)
    return out


def test_the_c_tripod_builds_unchanged_into_an_f411_elf(tripod_elf):
    e = layout(tripod_elf)
    assert e["machine"] == "EM_ARM" and e["class"] == 32
    assert e["flags"] & EF_ARM_ABI_FLOAT_HARD                   # floats in s0-s15
    assert "Tag_CPU_arch: v7E-M" in e["attributes"]
    assert "Tag_FP_arch: VFPv4-D16" in e["attributes"]
    assert "Tag_THUMB_ISA_use: Thumb-2" in e["attributes"]
    sym = e["symbols"]
    # the vector table at the start of flash: the stack's top, then the reset vector
    assert e["sections"][".isr_vector"][0] == 0x08000000
    assert e["vector"][0] == 0x20000000 + 128 * 1024 == sym["_estack"]
    assert e["vector"][1] == sym["Reset_Handler"] | 1 == e["entry"]
    assert e["vector"][15] == sym["SysTick_Handler"] | 1           # the HAL's 1 ms tick
    assert e["vector"][16 + 38] == sym["USART2_IRQHandler"] | 1    # IRQ 38: USART2
    assert e["vector"][3] == sym["Default_Handler"] | 1            # HardFault: not handled
    assert len(e["vector"]) == 16 + 86
    for name, (addr, size) in e["sections"].items():
        where = SRAM if name in (".data", ".bss", "._user_heap_stack") else FLASH
        assert addr in where and addr + size - 1 in where, name
    assert {"main", "HAL_UART_Transmit", "SystemClock_Config100MHz"} <= set(sym)
    assert e["has_dwarf"]                                            # for GDB and coverage


def test_the_same_main_c_still_builds_for_the_host(tmp_path):
    out = c_sdk.build([str(TRIPOD)], tmp_path / "c_tripod")
    assert os.access(out, os.X_OK) and out.read_bytes()[:4] == b"\x7fELF"
    with open(out, "rb") as f:
        assert ELFFile(f)["e_machine"] != "EM_ARM"


def test_the_register_definitions_match_rm0383s_maps(tmp_path):
    """register_layout.c asserts each offset at compile time: it builds only if they hold."""
    c_sdk.build([str(ELF_FW / "register_layout.c")], tmp_path / "layout.elf",
                target="stm32f411")


def test_compiler_flags_pass_through_for_both_targets(tmp_path):
    src = tmp_path / "pi.c"
    src.write_text('#include "stm32f4xx_hal.h"\n#include <math.h>\n'
                   "volatile double half_turn = M_PI;\n"
                   "#ifndef ANSWER\n#error no ANSWER\n#endif\n"
                   "int main(void) { return ANSWER; }\n")
    for target in ("host", "stm32f411"):
        # gnu11 by default, as CubeIDE: M_PI is visible; -D reaches the compiler
        proc = hexhil("sdk", "build", "--target", target, str(src), "-o",
                      str(tmp_path / f"pi-{target}"), "-DANSWER=42", "-O0", "-fno-common",
                      "-Wshadow")
        assert proc.returncode == 0, proc.stderr
        # strict C11 hides M_PI: the flag reached the compiler, the error is one line
        proc = hexhil("sdk", "build", "--target", target, str(src), "-o",
                      str(tmp_path / f"pi-{target}"), "-DANSWER=1", "-std=c11")
        lines = proc.stderr.strip().splitlines()
        assert proc.returncode == 2 and len(lines) == 1 and "M_PI" in lines[0], proc.stderr
        proc = hexhil("sdk", "build", "--target", target, str(src), "-o",
                      str(tmp_path / f"pi-{target}"))
        assert proc.returncode == 2 and "no ANSWER" in proc.stderr
    # an optional level never swallows the source that follows it
    proc = hexhil("sdk", "build", "-O", str(src), "-o", str(tmp_path / "x"))
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1 and "not an optimisation level" in lines[0]


def test_a_bare_build_links_only_the_linker_script(tmp_path):
    fw = c_sdk.build([str(ELF_FW / "bare_metal.c")], tmp_path / "bare.elf",
                     target="stm32f411", bare=True)
    e = layout(fw)
    sym = e["symbols"]
    assert e["vector"][1] == sym["Reset_Handler"] | 1 and len(e["vector"]) == 16
    assert not {"HAL_Init", "printf", "_write", "SystemInit"} & set(sym)
    # a build flag changes what is built: -DNO_DIRECTION never drives PA1 high
    other = c_sdk.build([str(ELF_FW / "bare_metal.c")], tmp_path / "nodir.elf",
                        ("-DNO_DIRECTION",), target="stm32f411", bare=True)
    assert other.read_bytes() != fw.read_bytes()
    with pytest.raises(UserError, match="bare builds for the board only"):
        c_sdk.build([str(ELF_FW / "bare_metal.c")], tmp_path / "x", bare=True)
    with pytest.raises(UserError, match="unknown target 'stm32f405': one of host, stm32f411"):
        c_sdk.build([str(ELF_FW / "bare_metal.c")], tmp_path / "x", target="stm32f405")


def test_a_firmware_whose_data_does_not_fit_the_ram_fails_to_link_in_one_line(tmp_path):
    src = tmp_path / "big.c"
    src.write_text('#include "stm32f4xx_hal.h"\nuint8_t big[120 * 1024];\n'
                   "int main(void) { big[1] = 1; return big[2]; }\n")
    proc = hexhil("sdk", "build", "--target", "stm32f411", str(src), "-o",
                  str(tmp_path / "big.elf"))
    lines = proc.stderr.strip().splitlines()
    # 120 KB of .bss and the 24 KB heap and stack reserve are more than the F411's 128 KB
    assert proc.returncode == 2 and len(lines) == 1 and "RAM" in lines[0], proc.stderr


def test_sdk_flags_for_the_board_build_the_c_tripod_from_a_users_makefile(tmp_path):
    proc = hexhil("sdk", "flags", "--target", "stm32f411", "--lib-dir", str(tmp_path / "lib"))
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert [ln.split()[:2] for ln in lines] == [["CC", "="], ["CFLAGS", "+="],
                                                ["LDFLAGS", "+="], ["LDLIBS", "+="]]
    assert "-mfloat-abi=hard" in lines[1] and "--specs=nano.specs" in lines[2]
    (tmp_path / "flags.mk").write_text(proc.stdout)
    (tmp_path / "Makefile").write_text("include flags.mk\nfw.elf: main.c\n"
                                       "\t$(CC) $(CFLAGS) $(LDFLAGS) $^ $(LDLIBS) -o $@\n")
    (tmp_path / "main.c").write_text(TRIPOD.read_text())
    subprocess.run(["make", "-s", "fw.elf"], cwd=tmp_path, check=True)
    e = layout(tmp_path / "fw.elf")
    # the whole library is linked: the vector table and startup come with it
    assert e["vector"][1] == e["symbols"]["Reset_Handler"] | 1
    assert e["vector"][15] == e["symbols"]["SysTick_Handler"] | 1


def test_a_missing_toolchain_is_one_line_naming_what_to_install(tmp_path, monkeypatch):
    env = {**os.environ, "PATH": str(tmp_path)}   # no arm-none-eabi-gcc on it
    # a process of its own: this one has found the toolchain already
    proc = hexhil_process("sdk", "build", "--target", "stm32f411", str(TRIPOD), "-o",
                          str(tmp_path / "fw.elf"), env=env)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert "arm-none-eabi-gcc" in lines[0]
    assert "apt-get install -y gcc-arm-none-eabi" in lines[0]
    assert "libnewlib-arm-none-eabi" in lines[0]


def test_a_gcc_without_newlib_is_named_too(tmp_path, monkeypatch):
    fake = tmp_path / "arm-none-eabi-gcc"   # answers -print-file-name as gcc does without it
    fake.write_text("#!/bin/sh\necho libc_nano.a\n")
    fake.chmod(0o755)
    monkeypatch.setenv("PATH", str(tmp_path))
    c_sdk.arm_compiler.cache_clear()
    try:
        with pytest.raises(UserError, match="newlib-nano's libc_nano.a is missing.*"
                                            "libnewlib-arm-none-eabi"):
            c_sdk.arm_compiler()
    finally:
        c_sdk.arm_compiler.cache_clear()


def test_make_toolchain_finds_the_installed_toolchain():
    proc = subprocess.run(["make", "-s", "toolchain"], cwd=ROOT, capture_output=True,
                          text=True)
    assert proc.returncode == 0 and proc.stdout == "", proc.stdout + proc.stderr


def test_the_flags_are_one_line_each_and_parse_as_the_compiler_would():
    lib = c_sdk.default_library_dir("stm32f411")
    assert lib.name == "c_sdk-stm32f411"
    flags = c_sdk.make_flags(lib / "libhexhil_f411.a", "stm32f411")
    assert shlex.split(flags["LDFLAGS"])[:4] == list(c_sdk.ARM_CPU)
