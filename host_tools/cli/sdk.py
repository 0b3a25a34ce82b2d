"""``hexhil sdk build|flags``: the C SDK (firmware/c_sdk/, an STM32Cube HAL subset) for a C
firmware that runs in lockstep with ``hexhil run --firmware``: a host executable over the
firmware link (docs/c-firmware.md) or, with ``--target stm32f411``, an ELF for the robot's
STM32F411 (docs/elf-firmware.md)."""
from __future__ import annotations

import argparse
import re

from hexhil.cli import actions

TARGETS = ("host", "stm32f411")


class _CompilerFlag(argparse.Action):
    """Collects -D, -I, -O, -std, -f, -W, -g in the order given, as the compiler spells them."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: object, option_string: str | None = None) -> None:
        flags = list(getattr(namespace, self.dest) or [])
        sep = "=" if option_string == "-std" else ""
        flags.append(f"{option_string}{sep}{values if values is not None else ''}")
        setattr(namespace, self.dest, flags)


def _level(pattern: str, what: str):
    """An optional level's check, so that ``-O main.c`` is not read as ``-Omain.c``."""
    def check(value: str) -> str:
        if re.fullmatch(pattern, value) is None:
            raise argparse.ArgumentTypeError(f"{value!r} is not {what}")
        return value
    return check


def _build(args: argparse.Namespace) -> int:
    from hexhil import c_sdk

    print(c_sdk.build(args.sources, args.output, tuple(args.cflags or ()), args.target,
                      args.bare))
    return 0


def _flags(args: argparse.Namespace) -> int:
    from hexhil import c_sdk

    lib = c_sdk.library(args.lib_dir or c_sdk.default_library_dir(args.target), args.target)
    for name, value in c_sdk.make_flags(lib, args.target).items():
        print(f"{name} {'=' if name == 'CC' else '+='} {value}")
    return 0


def _target(p: argparse.ArgumentParser) -> None:
    p.add_argument("--target", choices=TARGETS, default="host",
                   help="host: an executable over the firmware link (default); stm32f411: "
                        "an ELF for the robot's board (arm-none-eabi-gcc, newlib-nano)")


def register(sub: argparse._SubParsersAction) -> None:
    kinds = actions(sub, "sdk", "build a C firmware against the STM32Cube-style C SDK",
                        "KIND", __doc__)
    b = kinds.add_parser("build", help="compile C sources with the SDK into a firmware",
                         description="Compile main.c (and more .c files) with the SDK's "
                                     "stm32f4xx_hal.h and HAL into a firmware that "
                                     "`hexhil run SCENARIO --firmware FW` runs in lockstep: a "
                                     "host executable, or with --target stm32f411 an F411 "
                                     "ELF (Thumb-2, hard float, newlib-nano). Compiler flags "
                                     "pass through. Example: hexhil sdk build --target "
                                     "stm32f411 main.c -o fw.elf -DDEBUG -O0")
    b.add_argument("sources", nargs="+", metavar="FILE.c", help="the firmware's C sources")
    b.add_argument("-o", dest="output", required=True, metavar="FW", help="the firmware file")
    _target(b)
    b.add_argument("--bare", action="store_true",
                   help="stm32f411 only: link with the SDK's linker script alone (your own "
                        "vector table and Reset_Handler; no startup file, HAL or C library)")
    for flag, what in (("-D", "NAME[=VALUE]"), ("-I", "DIR"), ("-f", "OPTION"),
                       ("-W", "WARNING")):
        b.add_argument(flag, dest="cflags", action=_CompilerFlag, metavar=what,
                       help=f"passed to the compiler as {flag}{what}")
    b.add_argument("-O", dest="cflags", action=_CompilerFlag, nargs="?", metavar="LEVEL",
                   type=_level(r"[0-3sgz]|fast", "an optimisation level (0-3, s, g, z, fast)"),
                   help="optimisation, as -O0, -O2, -Os (default -O2)")
    b.add_argument("-std", dest="cflags", action=_CompilerFlag, metavar="STD",
                   help="C standard, as -std=c11 (default gnu11)")
    b.add_argument("-g", dest="cflags", action=_CompilerFlag, nargs="?", metavar="LEVEL",
                   type=_level(r"[0-3]|gdb|dwarf(-[2-5])?", "a debug level (0-3, gdb, dwarf-N)"),
                   help="debug information (the board's ELF always has -g)")
    b.set_defaults(func=_build)
    f = kinds.add_parser("flags", help="the compiler and library flags for your own Makefile",
                         description="Build the SDK library for the target and print the "
                                     "Makefile lines that use it: CFLAGS += ..., LDLIBS += "
                                     "... (and CC, LDFLAGS for --target stm32f411)")
    _target(f)
    f.add_argument("--lib-dir", metavar="DIR", help="where to build the library "
                   "(default: ~/.cache/hexhil/c_sdk, c_sdk-stm32f411 for the board)")
    f.set_defaults(func=_flags)
