"""One name for the firmware's runtime: ``runtime`` in the API, ``--runtime`` on the command
line, ``--python`` kept as its alias; a refusal names the flag as ``--runtime``."""
from __future__ import annotations

import pytest

from hexhil import cli
from hexhil.protocol.errors import UserError


@pytest.mark.parametrize("command", [["run", "s.toml"], ["test", "c.toml"],
                                     ["margin", "s.toml", "--expect", "e.toml"],
                                     ["replay", "t.mcap"], ["experiment", "tactile-hexapod"]])
def test_runtime_and_its_alias_set_the_same(command: list[str]) -> None:
    runtime = "cpython"
    parse = lambda flag: cli.build_parser(command).parse_args([*command, flag, runtime])  # noqa: E731
    assert parse("--runtime").python == parse("--python").python == runtime


def test_a_refusal_names_the_flag_runtime() -> None:
    err = UserError("firmware x.py brings its own runtime: leave out python", params=("python",))
    assert cli.flag_message(err).endswith("leave out --runtime")
    err = UserError("runtime must be one of micropython, cpython", params=("runtime",))
    assert cli.flag_message(err).startswith("--runtime must be one of")
