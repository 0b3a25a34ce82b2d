"""torch and distributed are extras (pyproject.toml): a command that needs a missing one says
in one line what to install and exits 2. The missing module is simulated in a child process
by a ``None`` entry in ``sys.modules`` (how Python marks a module that cannot be imported)."""
from __future__ import annotations

import subprocess
import sys
import tomllib

import pytest
from conftest import ROOT


def _hexhil_without(module: str, *argv: str) -> subprocess.CompletedProcess:
    code = (f"import sys; sys.modules[{module!r}] = None\n"
            f"from hexhil.cli import main\nsys.exit(main({list(argv)!r}))\n")
    return subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                          timeout=120)


@pytest.mark.parametrize("module, extra, argv", [
    ("torch", "grnn", ("grnn", "train", "{tmp}/ds", "--out", "{tmp}/m.pt")),
    ("torch", "grnn", ("grnn", "eval", "{tmp}/m.pt", "{tmp}/ds")),
    ("torch", "grnn", ("run", "scenarios/obstacles-low-large.toml", "--navigator", "grnn",
                       "--model", "{tmp}/m.pt")),
    ("distributed", "dask", ("experiment", "tactile-hexapod", "--quick", "--out", "{tmp}/out",
                             "--scheduler", "tcp://127.0.0.1:9")),
])
def test_a_missing_extra_is_one_line_naming_it(tmp_path, module, extra, argv):
    (tmp_path / "m.pt").write_bytes(b"")
    r = _hexhil_without(module, *(a.format(tmp=tmp_path) for a in argv))
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and f"pip install 'hexhil[{extra}]'" in lines[0], r.stderr
    assert not (tmp_path / "out").exists()   # refused before anything ran


def test_the_extras_are_declared_and_make_installs_them():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    core = " ".join(project["dependencies"])
    assert "torch" not in core and "distributed" not in core
    extras = project["optional-dependencies"]
    assert [d.split("=")[0] for d in extras["grnn"]] == ["torch"]
    assert [d.split(">")[0] for d in extras["dask"]] == ["distributed"]
    assert "-e '.[test,grnn,dask]'" in (ROOT / "Makefile").read_text()
