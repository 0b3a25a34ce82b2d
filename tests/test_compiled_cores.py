"""The package builds its compiled cores (setup.py's ``build_ext``, what ``pip install .``
and ``pip install -e .`` run) where their loaders look, with the flags that keep the
results' bits; ``hexhil --version`` says which are built; a core built from other structs
or constants than its Python side's is refused; each core is the one implementation of its
rules, and what needs a missing one (the drives, a servo, an ELF board) is refused in one
line."""
from __future__ import annotations

import ctypes
import dataclasses
import importlib
import subprocess
import sys
from pathlib import Path

import pytest

from hexhil.hil import native
from hexhil.protocol.errors import BadFile
from conftest import ROOT


def test_build_ext_puts_each_core_where_its_loader_looks(tmp_path: Path) -> None:
    subprocess.run([sys.executable, "setup.py", "-q", "build_ext", "--build-lib", str(tmp_path),
                    "--build-temp", str(tmp_path / "tmp")], cwd=ROOT, check=True,
                   capture_output=True)
    for name, path in native.CORES.items():
        built = tmp_path / "hexhil" / path.relative_to(ROOT)   # hil/ is hexhil.hil
        assert built.is_file(), name
        ctypes.CDLL(str(built))
        # the same compiler and flags as the tree's own build: the same library, byte for byte
        assert built.read_bytes() == path.read_bytes(), name


def test_the_build_keeps_the_flags_the_bits_depend_on() -> None:
    text = (ROOT / "setup.py").read_text()
    for flag in ("-mcpu=baseline", "-O2", "-ffp-contract=off"):
        assert f'"{flag}"' in text


def test_version_names_every_core() -> None:
    out = subprocess.run([sys.executable, "-m", "hexhil.cli", "--version"],
                         capture_output=True, text=True, check=True).stdout.splitlines()
    assert out[0].startswith("hexhil ")
    assert [line.split(":")[0].strip() for line in out[1:]] == list(native.CORES)
    assert all(": compiled (" in line for line in out[1:]), out


def test_a_missing_core_is_refused_where_it_is_needed_in_one_line(tmp_path: Path) -> None:
    missing = tmp_path / "_gone_core.so"
    assert native.load_library(missing) is None
    with pytest.raises(BadFile) as exc:
        native.require(None, missing, "a servo")
    assert str(exc.value) == ("a servo needs compiled core _gone_core.so, which is not built: "
                              "pip install -e . (or make) builds it")


def test_an_unloadable_core_says_so(tmp_path: Path) -> None:
    stale = tmp_path / "_stale_core.so"
    stale.write_bytes(b"not an ELF")
    assert native.load_library(stale) is None
    with pytest.raises(BadFile, match=r"which is not loadable \(.*\): pip install") as exc:
        native.require(None, stale, "an ELF board")
    assert "\n" not in str(exc.value)


def test_each_core_was_built_with_the_layout_its_python_side_reads() -> None:
    for name, module in native.LAYOUTS.items():
        layout = importlib.import_module(module).LAYOUT
        assert native.load_library(native.CORES[name], layout=layout) is not None, name


def test_a_core_built_with_other_structs_is_refused_in_one_line() -> None:
    layout = importlib.import_module(native.LAYOUTS["drive bank"]).LAYOUT
    other = dataclasses.replace(layout, constants=[("HX_OTHER", 1)])
    with pytest.raises(BadFile) as exc:
        native.load_library(native.CORES["drive bank"], layout=other)
    text = str(exc.value)
    assert "_drive_core.so was built with other structs" in text and "\n" not in text


def test_a_layout_refuses_a_constant_named_twice() -> None:
    layout = importlib.import_module(native.LAYOUTS["ELF board"]).LAYOUT
    with pytest.raises(ValueError, match="HX_BOARD_LAYOUT_H: constants named twice: TC$"):
        dataclasses.replace(layout, constants=[*layout.constants, ("TC", 1)])


def test_the_header_says_what_the_python_side_lays_out() -> None:
    layout = importlib.import_module(native.LAYOUTS["servo bank and reads"]).LAYOUT
    header = layout.header()
    assert "#define AX12_MOVING_SPEED 32\n" in header
    assert "    uint8_t present_stale;\n" in header   # Servo's _present_stale
    assert "    const struct bank *bank;\n" in header
    assert f'#define HX_LAYOUT "{layout.fingerprint()}"' in header


def test_drives_without_their_core_are_refused_in_one_line(monkeypatch) -> None:
    import numpy as np

    from hexhil.hil.world import drive_core
    from hexhil.hil.world.actuator import DriveBank

    monkeypatch.setattr(drive_core, "_LIB", None)   # as where the library is missing
    with pytest.raises(BadFile, match=r"drive bank needs compiled core _drive_core.so.*it$"):
        DriveBank(np.zeros(2))


def test_servos_without_their_core_are_refused_in_one_line(monkeypatch) -> None:
    from hexhil.hil.servobus import servo_rules
    from hexhil.hil.servobus.ax12_servo import Servo

    monkeypatch.setattr(servo_rules, "_LIB", None)   # as where the library is missing
    with pytest.raises(BadFile, match=r"^a servo needs compiled core _servo_core.so.*builds it$"):
        Servo(1)
