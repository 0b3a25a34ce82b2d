"""The C SDK (firmware/c_sdk/): build a C firmware against it for the host, and the flags a
user's own Makefile needs (``hexhil sdk build``, ``hexhil sdk flags``, docs/c-firmware.md).

The compiler is the machine's ``cc``/``gcc`` (``$CC`` first), else the pinned ``ziglang``
package's ``zig cc`` when it is installed: a fresh clone builds with no hand installs.
"""
from __future__ import annotations

import importlib.util
import logging
import os
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

from protocol.errors import UserError

ROOT = Path(__file__).resolve().parent.parent
SDK_DIR = ROOT / "firmware" / "c_sdk"
INCLUDE_DIR = SDK_DIR / "include"
SOURCES = tuple(sorted((SDK_DIR / "src").glob("*.c")))
LIBRARY = "hexhil_hal"      # libhexhil_hal.a: the link client and the HAL
CFLAGS = ("-std=c11", "-O2", "-Wall", "-Werror")
LDLIBS = ("-lm",)
log = logging.getLogger(__name__)


def compiler() -> list[str]:
    """The C compiler's command: ``$CC``, else cc or gcc, else ``python -m ziglang cc``."""
    if os.environ.get("CC"):
        return shlex.split(os.environ["CC"])
    for name in ("cc", "gcc"):
        path = shutil.which(name)
        if path:
            return [path]
    if importlib.util.find_spec("ziglang") is not None:
        return [sys.executable, "-m", "ziglang", "cc"]
    raise UserError("no C compiler: install gcc, or `pip install ziglang` (the test extra)")


def _compile(args: list[str], what: str) -> None:
    proc = subprocess.run(args, capture_output=True, text=True)
    if proc.returncode != 0:
        errors = [ln for ln in proc.stderr.splitlines() if "error" in ln] or \
            proc.stderr.strip().splitlines() or [f"exit {proc.returncode}"]
        log.info("compiler output:\n%s", proc.stderr)
        raise UserError(f"{what} does not build: {errors[0]}"
                        + (f" (and {len(errors) - 1} more errors)" if len(errors) > 1 else ""))


def _sources(paths: list[str]) -> list[Path]:
    if not paths:
        raise UserError("give at least one C source file (main.c)")
    out = []
    for p in paths:
        path = Path(p)
        if path.suffix != ".c":
            raise UserError(f"{p}: not a C source (.c)")
        if not path.is_file():
            raise UserError(f"{p}: no such file")
        out.append(path)
    return out


def build(sources: list[str], output: str | Path, cflags: tuple[str, ...] = ()) -> Path:
    """Compile ``sources`` with the SDK into the executable ``output``; returns its path."""
    srcs = _sources(sources)
    out = Path(output)
    if out.is_dir():
        raise UserError(f"-o {output}: is a folder (give the executable's file name)")
    if not out.parent.is_dir():
        raise UserError(f"-o {output}: the folder {out.parent} does not exist")
    _compile([*compiler(), *CFLAGS, *cflags, f"-I{INCLUDE_DIR}", *map(str, srcs),
              *map(str, SOURCES), "-o", str(out), *LDLIBS], ", ".join(map(str, srcs)))
    return out


def library(folder: str | Path) -> Path:
    """``lib<LIBRARY>.a`` of the SDK in ``folder`` (built when missing or older than a
    source); returns its path."""
    where = Path(folder)
    where.mkdir(parents=True, exist_ok=True)
    lib = where / f"lib{LIBRARY}.a"
    newest = max(p.stat().st_mtime for p in (*SOURCES, *INCLUDE_DIR.glob("*.h"),
                                             *(SDK_DIR / "src").glob("*.h")))
    if lib.exists() and lib.stat().st_mtime >= newest:
        return lib
    objects = []
    for src in SOURCES:
        obj = where / (src.stem + ".o")
        _compile([*compiler(), *CFLAGS, f"-I{INCLUDE_DIR}", "-c", str(src), "-o", str(obj)],
                 str(src))
        objects.append(str(obj))
    ar = shutil.which("ar")
    if ar is None:
        if importlib.util.find_spec("ziglang") is None:
            raise UserError("no `ar` to make the SDK library (install binutils)")
        cmd = [sys.executable, "-m", "ziglang", "ar"]
    else:
        cmd = [ar]
    _compile([*cmd, "rcs", str(lib), *objects], f"lib{LIBRARY}.a")
    return lib


def default_library_dir() -> Path:
    """Where ``hexhil sdk flags`` keeps the library: the user's cache."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "hexhil" / "c_sdk"


def make_flags(lib: Path) -> dict[str, str]:
    """The Makefile variables that build a firmware against ``lib``."""
    return {"CFLAGS": " ".join((*CFLAGS, f"-I{INCLUDE_DIR}")),
            "LDLIBS": f"-L{lib.parent} -l{LIBRARY} " + " ".join(LDLIBS)}
