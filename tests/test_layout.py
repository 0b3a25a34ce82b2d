"""The project's shape, held: the papers' packages above the toolkit (never
imported by it), one scenario form (only hil/scenario/ reads the data as written), the run's
seams typed, ``RunResult`` frozen, and library errors in the API's terms (the CLI adds the
flags). The floors, circles and line caps are tests/test_architecture.py's."""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from tests.test_architecture import ROOT, SHELL, _library_modules, _modules, imported, syntax_nodes


# --- the papers apart, one scenario form, the seams typed ------------------------
# The papers' reproductions sit above the toolkit: nothing of the toolkit imports them; the
# toolkit meets them through host_tools/plugins.py, which they register into. The CLI is the
# shell over both (``hexhil experiment``, ``hexhil grnn``, ``hexhil beams`` are theirs).
PAPERS = "hexhil.papers"
PAPERS_DIR = "host_tools/papers"


def _toolkit_modules() -> list[Path]:
    return [p for p in _modules()
            if not p.relative_to(ROOT).as_posix().startswith((PAPERS_DIR + "/", SHELL + "/"))]


def paper_imports(path: Path) -> list[str]:
    """Every import of the papers' package in a file, nested ones and ``from hexhil
    import papers`` too."""
    bad = []
    for node in syntax_nodes(path):
        names = imported(node)
        if isinstance(node, ast.ImportFrom) and node.module == "hexhil":
            names += [f"hexhil.{a.name}" for a in node.names]
        bad += [f"line {node.lineno}: imports {n}" for n in names
                if n == PAPERS or n.startswith(PAPERS + ".")]
    return bad


@pytest.mark.parametrize("path", _toolkit_modules(), ids=lambda p: str(p.relative_to(ROOT)))
def test_the_toolkit_never_imports_the_papers(path: Path) -> None:
    assert not paper_imports(path)


def test_the_paper_import_checker_sees_a_violation(tmp_path: Path) -> None:
    src = tmp_path / "m.py"
    src.write_text("def f():\n    from hexhil.papers.beam_traversal import planner\n"
                   "from hexhil import papers, plugins\nimport hexhil.papers\n")
    assert paper_imports(src) == ["line 3: imports hexhil.papers",
                                  "line 4: imports hexhil.papers",
                                  "line 2: imports hexhil.papers.beam_traversal"]


def test_the_papers_packages_exist_and_register_their_plugins() -> None:
    from hexhil.hil.scenario import WorldKind
    from hexhil import papers, plugins

    assert {p.name for p in (ROOT / PAPERS_DIR).iterdir() if p.is_dir()} >= {
        "tactile_hexapod", "beam_traversal"}
    assert papers.__name__ == PAPERS and callable(plugins.stepped_run(WorldKind.BEAMS))
    assert callable(plugins.navigator_plan("grnn")) and callable(plugins.navigator_plan("model"))


# One scenario form: only hil/scenario/ reads a scenario's data as written; everything else
# takes the typed ``Scenario`` or its sections. A raw read is the written data's attribute,
# or a section's name used as a key (``sc["world"]``, ``scenario.get("faults", {})``) on
# something named like a scenario.
SCENARIO_DIR = "hil/scenario"
SECTIONS = {"scenario", "bus", "firmware", "gait", "faults", "world", "beams", "traversal",
            "_path"}


def _scenario_like(node: ast.expr) -> bool:
    name = ast.unparse(node).split(".")[-1].split("(")[0].lower()
    return name in ("sc", "cfg", "config", "data") or "scenario" in name


def raw_scenario_reads(path: Path) -> list[str]:
    bad = []
    for node in syntax_nodes(path):
        if isinstance(node, ast.Attribute) and node.attr == "written":
            bad.append(f"line {node.lineno}: .written")
        key, obj = None, None
        if isinstance(node, ast.Subscript):
            key, obj = node.slice, node.value
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) \
                and node.func.attr in ("get", "setdefault") and node.args:
            key, obj = node.args[0], node.func.value
        if isinstance(key, ast.Constant) and key.value in SECTIONS and _scenario_like(obj):
            bad.append(f"line {node.lineno}: {ast.unparse(node)}")
    return bad


def _outside_the_scenario_package() -> list[Path]:
    """The host's modules (the firmware never sees a scenario: it gets its settings in the
    link's hello) but the scenario package's."""
    return [p for p in _modules() if p.relative_to(ROOT).parts[0] in ("hil", "host_tools")
            and not p.relative_to(ROOT).as_posix().startswith(SCENARIO_DIR + "/")]


@pytest.mark.parametrize("path", _outside_the_scenario_package(),
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_no_raw_scenario_reads_outside_the_scenario_package(path: Path) -> None:
    assert not raw_scenario_reads(path)


def test_the_raw_read_checker_sees_a_violation(tmp_path: Path) -> None:
    src = tmp_path / "m.py"
    src.write_text("def f(sc, scenario, rows, self):\n    a = sc['world']\n"
                   "    b = scenario.get('faults', {})\n    c = self.scenario['gait']\n"
                   "    d = rows['gait']\n    e = sc.world.kind\n    f = self.config.written\n")
    assert raw_scenario_reads(src) == ["line 2: sc['world']",
                                       "line 3: scenario.get('faults', {})",
                                       "line 4: self.scenario['gait']",
                                       "line 7: .written"]


# The run's seams are typed: what takes a recorder, a world, a bus, a link server or a CAN
# gateway names its Protocol (hil/seams.py) or class, never ``Any``; a world's actuators are
# hil/seams.py ``Actuator``s.
SEAM_NAMES = {"recorder", "world", "bus", "server", "can_server", "gateway"}


def _is_any(annotation: ast.expr) -> bool:
    """``Any``, ``Any | None``, ``Optional[Any]`` (quoted or not)."""
    text = ast.unparse(annotation).strip("'\"")
    parts = {p.strip() for p in text.replace("Optional[Any]", "Any").split("|")} - {"None"}
    return "Any" in parts


def untyped_seams(path: Path) -> list[str]:
    bad = []
    for node in syntax_nodes(path):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            args = node.args
            for a in [*args.posonlyargs, *args.args, *args.kwonlyargs]:
                if a.arg in SEAM_NAMES and a.annotation is not None \
                        and _is_any(a.annotation):
                    bad.append(f"line {a.lineno}: {a.arg}: {ast.unparse(a.annotation)}")
            if node.name == "actuators" and node.returns is not None \
                    and "Any" in ast.unparse(node.returns):
                bad.append(f"line {node.lineno}: actuators() -> {ast.unparse(node.returns)}")
        if isinstance(node, ast.AnnAssign) and isinstance(node.target, (ast.Name, ast.Attribute)):
            name = node.target.id if isinstance(node.target, ast.Name) else node.target.attr
            if name in SEAM_NAMES and _is_any(node.annotation):
                bad.append(f"line {node.lineno}: {name}: {ast.unparse(node.annotation)}")
    return bad


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(ROOT)))
def test_the_seams_are_typed(path: Path) -> None:
    assert not untyped_seams(path)


def test_the_seam_checker_sees_a_violation(tmp_path: Path) -> None:
    src = tmp_path / "m.py"
    src.write_text("class W:\n    world: Any\n    def actuators(self) -> Sequence[Any]: ...\n"
                   "def f(recorder: Any = None, *, can_server: 'Any | None' = None,\n"
                   "      bus: Bus = None, rows: Any = None): ...\n")
    assert sorted(untyped_seams(src)) == ["line 2: world: Any",
                                          "line 3: actuators() -> Sequence[Any]",
                                          "line 4: can_server: 'Any | None'",
                                          "line 4: recorder: Any"]


def test_run_result_is_frozen_and_its_parts_typed() -> None:
    import dataclasses
    import typing

    from hexhil.hil import run_result

    assert run_result.RunResult.__dataclass_params__.frozen
    hints = typing.get_type_hints(run_result.RunResult)
    assert hints["firmware"] is run_result.FirmwareStats
    assert hints["body"] is run_result.BodyDisplacement
    assert typing.get_args(hints["world"]) == (run_result.BeamsOutcome, run_result.HexapodOutcome,
                                               type(None))
    assert hints["no_servo_answered"] == str | None and hints["interrupted"] is bool
    for part in (run_result.FirmwareStats, run_result.BodyDisplacement, run_result.BeamsOutcome,
                 run_result.HexapodOutcome):
        assert part.__dataclass_params__.frozen
    with pytest.raises(dataclasses.FrozenInstanceError):
        run_result.RunResult("none").cycles = 1  # type: ignore[misc]


# Library errors say what is wrong in the API's terms; the CLI writes the parameters they
# name as its flags (host_tools/cli ``flag_message``).
FLAG_IN_TEXT = re.compile(r"(^|[\s('])--[a-z]")


def flags_in_errors(path: Path) -> list[str]:
    bad = []
    for node in syntax_nodes(path):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) \
                and node.func.id == "UserError" and node.args:
            text = "".join(c.value for c in ast.walk(node.args[0])
                           if isinstance(c, ast.Constant) and isinstance(c.value, str))
            if FLAG_IN_TEXT.search(text):
                bad.append(f"line {node.lineno}: {text!r}")
    return bad


@pytest.mark.parametrize("path", _library_modules(), ids=lambda p: str(p.relative_to(ROOT)))
def test_library_errors_name_no_cli_flags(path: Path) -> None:
    assert not flags_in_errors(path)


def test_the_cli_writes_the_parameters_as_flags(tmp_path: Path) -> None:
    from hexhil.cli import flag_message
    from hexhil.protocol.errors import UserError

    src = tmp_path / "m.py"
    src.write_text("raise UserError(f'--rate must be >= 0, got {r}')\n"
                   "raise UserError('rate must be >= 0', params=('rate',))\n")
    assert flags_in_errors(src) == ["line 1: '--rate must be >= 0, got '"]
    err = UserError("firmware fw.py brings its own runtime: leave out python (micropython)",
                    params=("firmware", "python"))
    assert flag_message(err) == ("--firmware fw.py brings its own runtime: leave out --runtime "
                                 "(micropython)")
    assert flag_message(UserError("x.toml: world needs a [world] section", params=("world",))) \
        == "x.toml: --world needs a [world] section"
    assert flag_message(UserError("rate must be >= 0")) == "rate must be >= 0"
    assert flag_message(UserError("firmware x.c: not executable (build a C firmware)",
                                  params=("firmware",))) == \
        "--firmware x.c: not executable (build a C firmware)"
