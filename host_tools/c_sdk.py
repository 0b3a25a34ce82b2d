"""The C SDK (firmware/c_sdk/): build a C firmware against it for the host or for the
robot's STM32F411, and the flags a user's own Makefile needs (``hexhil sdk build``,
``hexhil sdk flags``, docs/c-firmware.md, docs/elf-firmware.md).

For the host the compiler is the machine's ``cc``/``gcc`` (``$CC`` first), else the pinned
``ziglang`` package's ``zig cc``: a fresh clone builds with no hand installs. For the board it
is Debian's ``arm-none-eabi-gcc`` with newlib-nano (``make`` installs them where it may).
"""
from __future__ import annotations

import enum
import functools
import importlib.util
import logging
import os
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

from hexhil.hil.link.firmware_process import ROOT
from hexhil.protocol.errors import BadFile, BadValue, UserError

SDK_DIR = ROOT / "firmware" / "c_sdk"
INCLUDE_DIR = SDK_DIR / "include"
SOURCES = tuple(sorted((SDK_DIR / "src").glob("*.c")))
LIBRARY = "hexhil_hal"      # libhexhil_hal.a: the link client and the HAL
# both targets; -std=gnu11 as CubeIDE's default (M_PI and the other POSIX names visible)
CFLAGS = ("-std=gnu11", "-O2", "-Wall", "-Werror")
LDLIBS = ("-lm",)

F411_DIR = SDK_DIR / "stm32f411"
F411_INCLUDE_DIR = F411_DIR / "include"
F411_SOURCES = tuple(sorted((F411_DIR / "src").glob("*.c")))
LINKER_SCRIPT = F411_DIR / "stm32f411.ld"
F411_LIBRARY = "hexhil_f411"
ARM_CPU = ("-mcpu=cortex-m4", "-mthumb", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard")
# -g: the ELF keeps its DWARF for GDB and coverage; sections per function for --gc-sections
F411_CFLAGS = (*ARM_CPU, "-g", "-ffunction-sections", "-fdata-sections")
F411_LDFLAGS = (*ARM_CPU, "--specs=nano.specs", "--specs=nosys.specs", f"-T{LINKER_SCRIPT}",
                "-Wl,--gc-sections")
ARM_GCC = "arm-none-eabi-gcc"
ARM_PACKAGES = "gcc-arm-none-eabi binutils-arm-none-eabi libnewlib-arm-none-eabi"
LINE_ERRORS = ("error", "overflowed", "undefined reference", "multiple definition")
log = logging.getLogger(__name__)


class Target(str, enum.Enum):
    """What a firmware is built for: the host (over the firmware link) or the robot's MCU."""
    HOST = "host"
    STM32F411 = "stm32f411"

    @classmethod
    def of(cls, name: "Target | str") -> "Target":
        try:
            return cls(name)
        except ValueError:
            raise BadValue(f"unknown target {name!r}: one of "
                           + ", ".join(t.value for t in cls)) from None


def compiler() -> list[str]:
    """The host C compiler's command: ``$CC``, else cc or gcc, else ``python -m ziglang cc``."""
    if os.environ.get("CC"):
        return shlex.split(os.environ["CC"])
    for name in ("cc", "gcc"):
        path = shutil.which(name)
        if path:
            return [path]
    if importlib.util.find_spec("ziglang") is not None:
        return [sys.executable, "-m", "ziglang", "cc"]
    raise BadFile("no C compiler: install gcc, or `pip install ziglang` (the test extra)")


def _missing_toolchain(what: str) -> BadFile:
    return BadFile(f"no ARM toolchain ({what}): install it with `sudo apt-get install -y "
                   f"{ARM_PACKAGES}` (`make test` does it when run as root)")


@functools.lru_cache(maxsize=None)
def arm_compiler() -> str:
    """Debian's ``arm-none-eabi-gcc``, checked once for newlib-nano for the Cortex-M4F."""
    gcc = shutil.which(ARM_GCC)
    if gcc is None:
        raise _missing_toolchain(f"{ARM_GCC} is not on the PATH")
    found = subprocess.run([gcc, *ARM_CPU, "-print-file-name=libc_nano.a"],
                           capture_output=True, text=True).stdout.strip()
    if not os.path.isabs(found):
        raise _missing_toolchain("newlib-nano's libc_nano.a is missing")
    return gcc


def _compile(args: list[str], what: str) -> None:
    proc = subprocess.run(args, capture_output=True, text=True)
    if proc.returncode != 0:
        lines = proc.stderr.strip().splitlines()
        # the compiler's and the linker's own words, not collect2's "ld returned 1"
        errors = [ln for ln in lines if any(w in ln for w in LINE_ERRORS)
                  and "ld returned" not in ln] or lines or [f"exit {proc.returncode}"]
        log.info("compiler output:\n%s", proc.stderr)
        raise BadValue(f"{what} does not build: {errors[0]}"
                       + (f" (and {len(errors) - 1} more errors)" if len(errors) > 1 else ""))


def _sources(paths: list[str]) -> list[Path]:
    if not paths:
        raise BadValue("give at least one C source file (main.c)")
    out = []
    for p in paths:
        path = Path(p)
        if path.suffix != ".c":
            raise BadValue(f"{p}: not a C source (.c)")
        if not path.is_file():
            raise BadFile(f"{p}: no such file")
        out.append(path)
    return out


def _f411_includes() -> tuple[str, ...]:
    # the board's stm32f4xx_hal.h first; the shared hexhil_hal_api.h next to the host's
    return (f"-I{F411_INCLUDE_DIR}", f"-I{INCLUDE_DIR}")


def build(sources: list[str], output: str | Path, cflags: tuple[str, ...] = (),
          target: Target | str = Target.HOST, bare: bool = False) -> Path:
    """Compile ``sources`` with the SDK into ``output`` (a host executable, or an F411 ELF);
    returns its path. ``bare``: for the board, only the linker script (the firmware brings
    its own vector table and Reset_Handler; no startup file, HAL or C library)."""
    target = Target.of(target)
    srcs = _sources(sources)
    out = Path(output)
    if out.is_dir():
        raise BadFile(f"-o {output}: is a folder (give the firmware's file name)")
    if not out.parent.is_dir():
        raise BadFile(f"-o {output}: the folder {out.parent} does not exist")
    what = ", ".join(map(str, srcs))
    if target is Target.HOST:
        if bare:
            raise UserError("bare builds for the board only (target stm32f411)",
                            params=("bare", "target"))
        _compile([*compiler(), *CFLAGS, *cflags, f"-I{INCLUDE_DIR}", *map(str, srcs),
                  *map(str, SOURCES), "-o", str(out), *LDLIBS], what)
    elif bare:
        _compile([arm_compiler(), *CFLAGS, *F411_CFLAGS, "-ffreestanding", *cflags,
                  *map(str, srcs), "-nostdlib", f"-T{LINKER_SCRIPT}", "-Wl,--gc-sections",
                  "-o", str(out), "-lgcc"], what)
    else:
        _compile([arm_compiler(), *CFLAGS, *F411_CFLAGS, *cflags, *_f411_includes(),
                  *map(str, srcs), *map(str, F411_SOURCES), *F411_LDFLAGS, "-o", str(out),
                  *LDLIBS], what)
    return out


def library(folder: str | Path, target: Target | str = Target.HOST) -> Path:
    """The SDK's static library for ``target`` in ``folder`` (built when missing or older
    than a source); returns its path."""
    target = Target.of(target)
    where = Path(folder)
    where.mkdir(parents=True, exist_ok=True)
    if target is Target.HOST:
        name, srcs, cc = LIBRARY, SOURCES, compiler()
        flags: tuple[str, ...] = (*CFLAGS, f"-I{INCLUDE_DIR}")
        headers = (*INCLUDE_DIR.glob("*.h"), *(SDK_DIR / "src").glob("*.h"))
    else:
        name, srcs, cc = F411_LIBRARY, F411_SOURCES, [arm_compiler()]
        flags = (*CFLAGS, *F411_CFLAGS, *_f411_includes())
        headers = (*INCLUDE_DIR.glob("*.h"), *F411_INCLUDE_DIR.glob("*.h"))
    lib = where / f"lib{name}.a"
    newest = max(p.stat().st_mtime for p in (*srcs, *headers))
    if lib.exists() and lib.stat().st_mtime >= newest:
        return lib
    objects = []
    for src in srcs:
        obj = where / f"{src.stem}.{target.value}.o"
        _compile([*cc, *flags, "-c", str(src), "-o", str(obj)], str(src))
        objects.append(str(obj))
    lib.unlink(missing_ok=True)
    _compile([*_archiver(target), "rcs", str(lib), *objects], f"lib{name}.a")
    return lib


def _archiver(target: Target) -> list[str]:
    if target is Target.STM32F411:
        return [str(Path(arm_compiler()).with_name("arm-none-eabi-ar"))]
    ar = shutil.which("ar")
    if ar is not None:
        return [ar]
    if importlib.util.find_spec("ziglang") is None:
        raise BadFile("no `ar` to make the SDK library (install binutils)")
    return [sys.executable, "-m", "ziglang", "ar"]


def default_library_dir(target: Target | str = Target.HOST) -> Path:
    """Where ``hexhil sdk flags`` keeps the library: the user's cache."""
    base = Path(os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")) / "hexhil"
    target = Target.of(target)
    return base / ("c_sdk" if target is Target.HOST else f"c_sdk-{target.value}")


def make_flags(lib: Path, target: Target | str = Target.HOST) -> dict[str, str]:
    """The Makefile variables that build a firmware against ``lib``. For the board the whole
    library is linked: its startup file (the vector table) and system calls are reached by
    no call of the firmware's."""
    if Target.of(target) is Target.HOST:
        return {"CFLAGS": " ".join((*CFLAGS, f"-I{INCLUDE_DIR}")),
                "LDLIBS": f"-L{lib.parent} -l{LIBRARY} " + " ".join(LDLIBS)}
    return {"CC": arm_compiler(),
            "CFLAGS": " ".join((*CFLAGS, *F411_CFLAGS, *_f411_includes())),
            "LDFLAGS": " ".join(F411_LDFLAGS),
            "LDLIBS": f"-L{lib.parent} -Wl,--whole-archive -l{F411_LIBRARY} "
                      "-Wl,--no-whole-archive " + " ".join(LDLIBS)}
