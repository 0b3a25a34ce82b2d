"""The suite's own rules: one ``hexhil()`` helper and one repository root (conftest.py), no
path into a virtual environment, nothing skipped for a missing package, and a test module
whose optional extra is missing is one failing test naming the extra instead of a
collection error."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from conftest import HEXHIL, ROOT, TESTS, hexhil, hexhil_in_process

FILES = sorted(p for p in TESTS.rglob("*.py") if p.name not in ("conftest.py", "test_suite.py"))


def test_one_hexhil_helper_and_no_venv_path() -> None:
    for path in FILES:
        text = path.read_text()
        assert not re.search(r"^def hexhil\(", text, re.M), f"{path.name}: use conftest.hexhil"
        assert ".venv" not in text, f"{path.name}: a path into a virtual environment"
        assert 'with_name("hexhil")' not in text, f"{path.name}: use conftest.HEXHIL"
        if path.name.startswith("test_"):   # helper modules serve bench/ too, without conftest
            assert not re.search(r"^(ROOT|HEXHIL) = ", text, re.M), \
                f"{path.name}: use conftest.ROOT and conftest.HEXHIL"


def test_nothing_skips_for_a_missing_package() -> None:
    for path in FILES:
        assert "importorskip" not in path.read_text(), path.name


def test_the_helper_runs_the_command_line() -> None:
    r = hexhil("--version")
    assert r.returncode == 0 and r.stdout.startswith("hexhil ")
    assert HEXHIL[1:] == ["-m", "hexhil.cli"]


def test_the_in_process_helper_gives_what_the_command_line_gives(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[gait]\nspeed = 1\n")
    for argv in (["--version"], ["run", str(bad)], ["protocol", "decode", "FF FF 01 02 01 FB"]):
        here, there = hexhil_in_process(*argv), hexhil(*argv)
        assert (here.returncode, here.stdout, here.stderr) == \
            (there.returncode, there.stdout, there.stderr), argv


def test_a_missing_extra_is_one_failing_test_not_a_collection_error(tmp_path: Path) -> None:
    shadow = tmp_path / "torch"
    shadow.mkdir()
    (shadow / "__init__.py").write_text(
        "raise ModuleNotFoundError(\"No module named 'torch'\", name='torch')\n")
    out = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                          "tests/test_grnn.py"], cwd=ROOT, capture_output=True, text=True,
                         env={"PYTHONPATH": str(tmp_path), "PATH": "/usr/bin:/bin"},
                         timeout=300)
    assert out.returncode == 1, out.stdout + out.stderr
    assert "error" not in out.stdout.splitlines()[-1], out.stdout
    assert "test_grnn.py needs torch, from the [grnn] extra" in out.stdout
    assert "1 failed" in out.stdout.splitlines()[-1]


def test_every_bench_module_imports_as_make_bench_imports_it() -> None:
    """``python -m bench`` has no tests folder on its path: a bench that reaches a test
    helper through conftest fails there while its smoke test passes here."""
    names = sorted(p.stem for p in (ROOT / "bench").glob("bench_*.py"))
    code = "import importlib\nfor n in %r:\n    importlib.import_module('bench.' + n)\n" % names
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
