"""What every test file shares: the tests folder on the import path (its helper modules),
``hexhil()`` to run the command line as a user does, ``hexhil_in_process()`` to run a
command without a new interpreter, and ``tool()`` (from mpy.py) to find a program that the
environment installed beside this interpreter."""
from __future__ import annotations

import contextlib
import io
import logging
import os
import subprocess
import sys
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent
ROOT = TESTS.parent
sys.path.insert(0, str(TESTS))

from mpy import tool  # noqa: E402  (re-exported: the test files import it from here)

# ``hexhil`` as a child process: the console script's own entry point, in this interpreter
HEXHIL = [sys.executable, "-m", "hexhil.cli"]


def hexhil(*argv: str | Path, timeout: float = 300, **kw) -> subprocess.CompletedProcess:
    """``hexhil ARGV...`` from the repository root, its output captured as text; ``kw``
    goes to ``subprocess.run`` (``env``, ``input``)."""
    return subprocess.run([*HEXHIL, *map(str, argv)], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout, **kw)


def hexhil_in_process(*argv: str | Path) -> subprocess.CompletedProcess:
    """``hexhil ARGV...`` through ``cli.main`` in this process, from the repository root: the
    exit status, stdout and stderr that ``hexhil()`` gives, without a new interpreter's
    start-up and imports (MuJoCo's; about a second of CPU each). For a test of what a command
    does; one of the process around it (signals, exit on Ctrl-C) uses ``hexhil()``."""
    from hexhil import cli

    out, err = io.StringIO(), io.StringIO()
    here = os.getcwd()
    # the loggers a command routes to the terminal: as a new process has them, then back
    loggers = [logging.getLogger(name) for name in ("hexhil", "hexhil.console")]
    before = [(log.handlers[:], log.level, log.propagate) for log in loggers]
    for log in loggers:
        log.handlers[:], log.propagate = [], True
        log.setLevel(logging.NOTSET)
    os.chdir(ROOT)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = cli.main([str(a) for a in argv])
            except SystemExit as exc:   # argparse's own exits: --help, --version
                code = exc.code if isinstance(exc.code, int) else 0
    finally:
        os.chdir(here)
        for log, (handlers, level, propagate) in zip(loggers, before):
            log.handlers[:] = handlers
            log.setLevel(level)
            log.propagate = propagate
    return subprocess.CompletedProcess([*HEXHIL, *map(str, argv)], code, out.getvalue(),
                                       err.getvalue())




# A test module that imports an optional extra the environment lacks is one failing test
# naming the extra, never a collection error that stops the whole run, and never a skip:
# `make test` installs every extra, so nothing there is left out silently.
EXTRAS = {"torch": "grnn", "distributed": "dask", "hypothesis": "test",
          "dynamixel_sdk": "test", "yourdfpy": "test", "websockets": "test",
          "atheris": "test", "ziglang": "test", "pypot": "pypot (make setup installs it)"}


class MissingExtra(pytest.Item):
    """Stands for a test module whose optional extra is not installed."""

    def __init__(self, *, message: str, **kw) -> None:
        super().__init__(**kw)
        self.message = message

    def runtest(self) -> None:
        pytest.fail(self.message, pytrace=False)

    def reportinfo(self) -> tuple[Path, int, str]:
        return self.path, 0, self.name


class ModuleNeedingExtras(pytest.Module):
    def collect(self):
        try:
            return super().collect()
        except pytest.Collector.CollectError as exc:
            missing = getattr(exc.__cause__, "name", None)
            if not isinstance(exc.__cause__, ModuleNotFoundError) or missing is None:
                raise
            top = missing.split(".")[0]
            if top not in EXTRAS:
                raise
            extra = EXTRAS[top]
            how = extra if " " in extra else f"the [{extra}] extra: pip install -e '.[{extra}]'"
            return [MissingExtra.from_parent(self, name=f"needs_{top}",
                                             message=f"{self.path.name} needs {top}, from {how}")]


def pytest_pycollect_makemodule(module_path: Path, parent: pytest.Collector) -> pytest.Module:
    return ModuleNeedingExtras.from_parent(parent, path=module_path)


# Property tests draw the same examples on every run (hypothesis' derandomize): a suite that
# passed on one clean clone passes on the next; a file's own settings may still ask for more
try:
    from hypothesis import settings as _hypothesis_settings
except ModuleNotFoundError:   # the [test] extra is missing: its modules say so (above)
    pass
else:
    _hypothesis_settings.register_profile("hexhil", derandomize=True)
    _hypothesis_settings.load_profile("hexhil")
