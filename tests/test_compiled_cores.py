"""The package builds its compiled cores (setup.py's ``build_ext``, what ``pip install .``
and ``pip install -e .`` run) where their loaders look, with the flags that keep the
results' bits; ``hexhil --version`` says which are built; a missing core is one warning."""
from __future__ import annotations

import ctypes
import logging
import subprocess
import sys
from pathlib import Path

from hil import native

ROOT = Path(__file__).resolve().parents[1]


def test_build_ext_puts_each_core_where_its_loader_looks(tmp_path: Path) -> None:
    subprocess.run([sys.executable, "setup.py", "-q", "build_ext", "--build-lib", str(tmp_path),
                    "--build-temp", str(tmp_path / "tmp")], cwd=ROOT, check=True,
                   capture_output=True)
    for name, path in native.CORES.items():
        built = tmp_path / path.relative_to(ROOT)
        assert built.is_file(), name
        ctypes.CDLL(str(built))
        # the same compiler and flags as the tree's own build: the same library, byte for byte
        assert built.read_bytes() == path.read_bytes(), name


def test_the_build_keeps_the_flags_the_bits_depend_on() -> None:
    text = (ROOT / "setup.py").read_text()
    for flag in ("-mcpu=baseline", "-O2", "-ffp-contract=off"):
        assert f'"{flag}"' in text


def test_version_names_every_core() -> None:
    out = subprocess.run([sys.executable, "-m", "host_tools.cli", "--version"],
                         capture_output=True, text=True, check=True).stdout.splitlines()
    assert out[0].startswith("hexhil ")
    assert [line.split(":")[0].strip() for line in out[1:]] == list(native.CORES)
    assert all(": compiled (" in line for line in out[1:]), out


def test_a_missing_core_is_one_warning_line(tmp_path: Path, caplog) -> None:
    missing = tmp_path / "_gone_core.so"
    with caplog.at_level(logging.WARNING, logger="hil.native"):
        assert native.load_library(missing) is None
        assert native.load_library(missing, keep_gil=True) is None   # a second loader
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 1 and "_gone_core.so is not built" in lines[0], lines
    assert "\n" not in lines[0]


def test_an_unloadable_core_says_so(tmp_path: Path, caplog) -> None:
    stale = tmp_path / "_stale_core.so"
    stale.write_bytes(b"not an ELF")
    with caplog.at_level(logging.WARNING, logger="hil.native"):
        assert native.load_library(stale) is None
    assert "not loadable" in caplog.records[0].getMessage()
