"""``hexhil sdk build|flags``: the C SDK (firmware/c_sdk/, an STM32Cube HAL subset over the
firmware link) for a C firmware that runs in lockstep with ``hexhil run --firmware``
(docs/c-firmware.md)."""
from __future__ import annotations

import argparse

from host_tools.cli import actions


def _build(args: argparse.Namespace) -> int:
    from host_tools import c_sdk

    print(c_sdk.build(args.sources, args.output))
    return 0


def _flags(args: argparse.Namespace) -> int:
    from host_tools import c_sdk

    lib = c_sdk.library(args.lib_dir or c_sdk.default_library_dir())
    for name, value in c_sdk.make_flags(lib).items():
        print(f"{name} += {value}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    kinds = actions(sub, "sdk", "build a C firmware against the STM32Cube-style C SDK",
                        "KIND", __doc__)
    b = kinds.add_parser("build", help="compile C sources with the SDK into an executable",
                         description="Compile main.c (and more .c files) with the SDK's "
                                     "stm32f4xx_hal.h and HAL into a host executable that "
                                     "`hexhil run SCENARIO --firmware FW` runs in lockstep. "
                                     "Example: hexhil sdk build main.c -o fw")
    b.add_argument("sources", nargs="+", metavar="FILE.c", help="the firmware's C sources")
    b.add_argument("-o", dest="output", required=True, metavar="FW", help="the executable")
    b.set_defaults(func=_build)
    f = kinds.add_parser("flags", help="the include and library flags for your own Makefile",
                         description="Build the SDK library (libhexhil_hal.a) and print the "
                                     "Makefile lines that use it: CFLAGS += ..., LDLIBS += ...")
    f.add_argument("--lib-dir", metavar="DIR", help="where to build the library "
                   "(default: ~/.cache/hexhil/c_sdk)")
    f.set_defaults(func=_flags)
