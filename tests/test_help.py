"""`--help` for every command and subcommand (walked from hexhil.cli.build_parser): no
reStructuredText markup leaks into it, and every option and positional says what it is."""
from __future__ import annotations

import argparse
import re

import pytest

from hexhil import cli

RST = re.compile(r"``|:(?:func|mod|class|meth|ref|py:\w+):`|\.\. \w+::")


def _parsers() -> list[tuple[str, argparse.ArgumentParser]]:
    """Every parser in the tree, each command's module imported (build_parser(argv) loads only
    argv[0]'s), as (its prog, the parser)."""
    found: list[tuple[str, argparse.ArgumentParser]] = []

    def walk(p: argparse.ArgumentParser) -> None:
        found.append((p.prog, p))
        for action in p._actions:
            if isinstance(action, argparse._SubParsersAction):
                for child in dict.fromkeys(action.choices.values()):
                    walk(child)

    top = cli.build_parser([])
    found.append((top.prog, top))
    for name in cli.COMMANDS:
        sub = next(a for a in cli.build_parser([name])._actions
                   if isinstance(a, argparse._SubParsersAction))
        walk(sub.choices[name])
    return found


PARSERS = _parsers()


def test_the_walk_reaches_every_command_and_action():
    progs = {prog for prog, _ in PARSERS}
    assert {f"hexhil {c}" for c in cli.COMMANDS} <= progs
    assert {"hexhil trace import-csv", "hexhil beams run", "hexhil grnn eval",
            "hexhil model urdf", "hexhil protocol decode"} <= progs


@pytest.mark.parametrize("prog,parser", PARSERS, ids=[prog for prog, _ in PARSERS])
def test_help_has_no_markup_and_every_argument_is_described(prog, parser):
    text = parser.format_help()
    assert not RST.search(text), f"{prog} --help shows markup: {RST.search(text).group(0)}"
    bare = []
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):   # each subcommand's line in the listing
            listed = {c.dest: c.help for c in a._choices_actions}
            bare += [f"{prog} {name}" for name in a.choices if not listed.get(name)]
        elif not a.help:
            bare.append(a.option_strings[0] if a.option_strings else a.dest)
    assert not bare, f"{prog}: no help for {bare}"
    assert parser.description or prog == "hexhil", f"{prog} has no description"


def test_json_is_described_the_same_everywhere():
    helps = {a.help for _, p in PARSERS for a in p._actions if "--json" in a.option_strings}
    assert helps and all(h.startswith(cli.JSON_HELP) for h in helps), helps


def test_a_positional_is_named_the_same_wherever_it_appears():
    shown: dict[str, set[str]] = {}
    for _, p in PARSERS:
        for a in p._actions:
            if not a.option_strings and not isinstance(a, argparse._SubParsersAction):
                shown.setdefault(a.dest, set()).add(str(a.metavar or a.dest))
    assert {dest: names for dest, names in shown.items() if len(names) > 1} == {}


def test_the_command_listing_says_what_each_command_says_of_itself():
    """``hexhil --help`` lists a command with the line that command registers: the listing
    a partial parser shows (cli.COMMANDS) cannot drift from it."""
    top = cli.build_parser([])
    sub = next(a for a in top._actions if isinstance(a, argparse._SubParsersAction))
    registered = {c.dest: c.help for c in sub._choices_actions}
    assert {name: text for name, (_, text) in cli.COMMANDS.items()} == registered
