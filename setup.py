"""The compiled cores, built by the package: ``pip install .`` and ``pip install -e .`` both
run ``build_ext``, which compiles each core with the pinned ziglang's ``cc`` (a build
requirement in pyproject.toml, so no system compiler is needed) into the plain shared
library its loader opens beside its Python module (hil/native.py).

The flags are the results' promise: ``-mcpu=baseline`` so that a tree copied to another
x86-64 machine still runs, and ``-ffp-contract=off`` (no fused multiply-add) so that the
floating-point cores round as numpy and CPython do, bit for bit.

A core's structs and constants are written once, in Python (hil/native.py ``Layout``): this
writes them as the header the core includes (``layout``: the module that holds them, and
the header's name), into the build's temporary folder; the library keeps its fingerprint.
"""
from __future__ import annotations

import importlib
import subprocess
import sys
import types
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

# -g0: no debug information, so no build folder's path in the library (the same bytes
# from pip's isolated build and from a checkout's)
COMMON = ["-mcpu=baseline", "-O2", "-g0", "-shared", "-fPIC"]
FLOAT = ["-ffp-contract=off"]   # numpy's and CPython's bits


ROOT = Path(__file__).resolve().parent
# the installed packages -> the repository's folders: the public API and command line are
# ``hexhil``, the simulator, the contracts and the firmware live under it, so that no generic
# top-level name (``protocol``, ``firmware``) is taken from other projects
FOLDERS = {"hexhil": "host_tools", "hexhil.hil": "hil", "hexhil.protocol": "protocol",
           "hexhil.firmware": "firmware"}


def _packages() -> list[str]:
    """Every package under the four folders (a folder with an ``__init__.py``)."""
    out = []
    for name, folder in FOLDERS.items():
        top = ROOT / folder
        out += [".".join((name, *init.parent.relative_to(top).parts))
                for init in sorted(top.rglob("__init__.py"))]
    return out


def _core(name: str, sources: list[str], flags: list[str], depends: list[str] = (),
          layout: tuple[str, str] | None = None) -> Extension:
    ext = Extension(name, sources=sources, depends=list(depends))
    ext.hexhil_flags = COMMON + flags   # type: ignore[attr-defined]
    ext.hexhil_layout = layout          # type: ignore[attr-defined]
    return ext


CORES = [
    _core("hexhil.hil.world._drive_core", ["hil/world/drive_core.c"], FLOAT,
          depends=["hil/world/drive_layout.py"],
          layout=("hexhil.hil.world.drive_layout", "drive_layout.h")),
    _core("hexhil.hil.servobus._servo_core",
          ["hil/servobus/servo_core.c", "hil/servobus/reads_core.c"], FLOAT,
          depends=["hil/servobus/servo_core.h", "hil/servobus/servo_layout.py"],
          layout=("hexhil.hil.servobus.servo_layout", "servo_layout.h")),
    _core("hexhil.hil.mcu._board_core", ["hil/mcu/board_core.c"], [],   # integers only
          depends=["hil/mcu/board_layout.py", "hil/mcu/armv7m.py", "hil/mcu/timebase.py",
                   "hil/mcu/platform.py", "hil/mcu/gpio_registers.py",
                   "hil/mcu/usart_registers.py"],
          layout=("hexhil.hil.mcu.board_layout", "board_layout.h")),
]


def _write_layout(module: str, header: str, folder: Path) -> None:
    """The core's header from its Layout (the source tree's hil/ and protocol/: plain
    Python and ctypes, importable in the build's isolated environment)."""
    if str(ROOT) not in sys.path:   # the chip's names, which protocol/ imports itself by
        sys.path.insert(0, str(ROOT))
    for name, source in FOLDERS.items():   # the installed names, their __init__ not run
        if name not in sys.modules:
            package = types.ModuleType(name)
            package.__path__ = [str(ROOT / source)]
            sys.modules[name] = package
    folder.mkdir(parents=True, exist_ok=True)
    (folder / header).write_text(importlib.import_module(module).LAYOUT.header())


class BuildCores(build_ext):
    """Each core as ``NAME.so`` (what its loader opens: no Python module, no ABI tag),
    compiled by ``zig cc`` with the core's flags and nothing of Python's own CFLAGS."""

    def get_ext_filename(self, fullname: str) -> str:
        return str(Path(*fullname.split("."))) + ".so"

    def build_extension(self, ext: Extension) -> None:
        out = Path(self.get_ext_fullpath(ext.name))
        out.parent.mkdir(parents=True, exist_ok=True)
        flags = list(ext.hexhil_flags)
        if ext.hexhil_layout is not None:
            include = Path(self.build_temp).resolve() / "hexhil_layouts"
            _write_layout(*ext.hexhil_layout, include)
            flags.append(f"-I{include}")
        cmd = [*_zig_cc(), *flags, "-o", str(out), *ext.sources]
        self.announce(" ".join(cmd), level=2)
        subprocess.run(cmd, check=True)


def _zig_cc() -> list[str]:
    try:
        import ziglang
    except ImportError:   # built without isolation in an environment that lacks it
        return [sys.executable, "-m", "ziglang", "cc"]
    return [str(Path(ziglang.__file__).with_name("zig")), "cc"]


setup(packages=_packages(), package_dir=FOLDERS, ext_modules=CORES,
      cmdclass={"build_ext": BuildCores})
