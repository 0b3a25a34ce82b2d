"""The errors a user can act on: one base, ``UserError``, whose kinds are also the built-in
error a Python caller already catches; exit statuses are the command line's alone."""
from __future__ import annotations

from pathlib import Path

import pytest

import hexhil as hx
from hexhil import cli
from hexhil.protocol.errors import BadFile, BadValue, UserError

ROOT = Path(__file__).resolve().parents[1]


def test_a_value_outside_its_rules_is_a_value_error() -> None:
    with pytest.raises(ValueError, match="duration_s must be positive") as got:
        hx.Run(ROOT / "scenarios" / "flat-tripod.toml", duration_s=-1)
    assert isinstance(got.value, BadValue) and isinstance(got.value, UserError)


def test_an_unwritable_trace_is_an_os_error(tmp_path: Path) -> None:
    with pytest.raises(OSError, match="is a directory") as got:
        hx.Run(ROOT / "scenarios" / "flat-tripod.toml", duration_s=0.1, trace=tmp_path)
    assert isinstance(got.value, BadFile) and isinstance(got.value, UserError)
    assert str(got.value).endswith("is a directory, not a trace file")


def test_the_base_alone_is_neither() -> None:
    err = UserError("another run is writing this trace now")
    assert not isinstance(err, (ValueError, OSError))


def test_the_command_line_maps_every_kind_to_exit_2(tmp_path: Path, capsys) -> None:
    scenario = str(ROOT / "scenarios" / "flat-tripod.toml")
    assert cli.main(["run", scenario, "--duration", "-1"]) == cli.EXIT_BAD_INPUT == 2
    assert cli.main(["run", scenario, "--duration", "0.1", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith("hexhil: --duration must be positive")
    assert err[-1].endswith("is a directory, not a trace file") and len(err) == 2
