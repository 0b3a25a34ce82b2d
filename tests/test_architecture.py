"""The floors hold: protocol/ at the bottom, firmware/ and hil/ on it and never on each
other, host_tools/ on top; no source file grows past 400 lines, none is named by a protocol
number, hil/'s top level stays small, and no module (Python or C) is in an import circle."""
from __future__ import annotations

import ast
import functools
import re
from pathlib import Path

import pytest
from conftest import ROOT

# What each floor may import from the project (its own floor included).
ALLOWED = {
    "protocol": {"protocol"},
    "firmware": {"protocol", "firmware"},
    "hil": {"protocol", "hil"},
    "host_tools": {"protocol", "hil", "host_tools"},
}
# host_tools/ stands on firmware/ too, but only here: the in-process runtime runs the
# firmware in the host; every other host tool meets it through the link.
FIRMWARE_RUNNERS = {"host_tools/in_process.py"}
# The host's end of the link paces its polling by the gate the firmware's HAL uses
# (firmware/hal/poll_gate.py): one rule for both ends, outside the link's contract.
LINK_PACERS = {"hil/link/firmware_process.py"}
MAX_LINES = 400
# the installed names of the host's floors (setup.py FOLDERS); protocol/ and firmware/ import
# each other by the chip's names, the top-level folders of the chip's filesystem
INSTALLED = {"hexhil.hil": "hil", "hexhil.protocol": "protocol", "hexhil.firmware": "firmware",
             "hexhil": "host_tools"}
CHIP_FLOORS = ("protocol", "firmware")


def floor_named(module: str, importer: str) -> str | None:
    """The floor a module name points into from a file of floor ``importer`` (None: not the
    project's). The host's floors write the installed names, the chip's its own; a chip name
    written on the host, or an installed name on the chip, is its own violation."""
    top, _, rest = module.partition(".")
    if top == "hexhil":
        floor = INSTALLED.get(f"hexhil.{rest.partition('.')[0]}", "host_tools")
        return floor if importer not in CHIP_FLOORS else f"{floor} (by its installed name)"
    if top in CHIP_FLOORS or top in ("hil", "host_tools"):
        return top if importer in CHIP_FLOORS else f"{top} (by a bare name)"
    return None


def _modules() -> list[Path]:
    return sorted(p for d in ALLOWED for p in (ROOT / d).rglob("*.py"))


def syntax_nodes(path: Path) -> tuple[ast.AST, ...]:
    """Every node of a Python file's tree in ``ast.walk``'s order, parsed once a process for
    each text: the checks here and in tests/test_layout.py each walk every file of the project."""
    return _walked(path.read_text(encoding="utf-8"))


@functools.cache
def _walked(source: str) -> tuple[ast.AST, ...]:
    return tuple(ast.walk(ast.parse(source)))


def imported(node: ast.AST) -> list[str]:
    """The modules an absolute import statement names (none for other nodes)."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
        return [node.module]
    return []


def project_imports(path: Path, importer: str) -> list[tuple[int, str]]:
    """(line, floor) of every project import in a file of floor ``importer``, nested ones
    too."""
    out = []
    for node in syntax_nodes(path):
        floors = [floor_named(n, importer) for n in imported(node)]
        out += [(node.lineno, f) for f in floors if f is not None]
    return out


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(ROOT)))
def test_imports_stay_on_or_below_their_floor(path: Path) -> None:
    rel = path.relative_to(ROOT)
    floor = rel.parts[0]
    allowed = ALLOWED[floor] | ({"firmware"} if rel.as_posix() in FIRMWARE_RUNNERS | LINK_PACERS
                                else set())
    bad = [f"line {line}: {floor} imports {pkg}" for line, pkg in project_imports(path, floor)
           if pkg not in allowed]
    assert not bad, bad


def test_the_walker_sees_a_violation(tmp_path: Path) -> None:
    src = tmp_path / "m.py"
    src.write_text("import os\ndef f():\n    from hexhil.firmware import config\n"
                   "from hexhil.hil.servobus.line import Bus\nimport protocol.errors\n"
                   "import hexhil as hx\n")
    assert sorted(project_imports(src, "hil")) == [
        (3, "firmware"), (4, "hil"), (5, "protocol (by a bare name)"), (6, "host_tools")]
    assert sorted(project_imports(src, "firmware")) == [
        (3, "firmware (by its installed name)"), (4, "hil (by its installed name)"),
        (5, "protocol"), (6, "host_tools (by its installed name)")]


# The host's programs beside the package (tests, benchmarks, fuzzers, examples) import it by
# its installed names too; the chip's programs among them (run by ``micropython`` or served to
# the link) by the chip's.
HOST_PROGRAMS = ("tests", "bench", "fuzz", "examples")
# (fuzz/hostile.py runs in both: it tries the installed name first)
CHIP_PROGRAMS = ("tests/micropython/", "tests/micropython_chip/", "tests/link_clients/",
                 "tests/fuzz_targets/", "tests/firmware/", "fuzz/hostile.py")


def _host_programs() -> list[Path]:
    return sorted(p for d in HOST_PROGRAMS for p in (ROOT / d).rglob("*.py")
                  if not p.relative_to(ROOT).as_posix().startswith(CHIP_PROGRAMS))


def test_host_programs_import_the_installed_names() -> None:
    files = _host_programs()
    assert len(files) > 100
    bad = {str(p.relative_to(ROOT)): [f"line {line}: {f}" for line, f in project_imports(p, "tests")
                                      if f.endswith("(by a bare name)")] for p in files}
    assert not {k: v for k, v in bad.items() if v}, bad


def test_no_source_file_over_400_lines() -> None:
    files = [p for d in (*ALLOWED, "bench", "fuzz", "tests") for p in (ROOT / d).rglob("*.py")]
    long = {str(p.relative_to(ROOT)): n for p in files
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_LINES}
    assert not long, long


# --- the CLI is a shell ----------------------------------------------
# Only host_tools/cli/ parses arguments, writes to the user's terminal and picks exit codes;
# library code returns values, raises UserError, and reports progress through a callback
# (host_tools/progress.py) or ``logging``. firmware/ is out of scope: its print() is the
# firmware's serial console, which the simulator captures (the serial digest). bench/ and
# fuzz/ are programs of their own (python -m bench, python -m fuzz) that print their tables.
SHELL = "host_tools/cli"
SHELL_MODULE = "hexhil.cli"
LIBRARY = ("protocol", "hil", "host_tools")
TERMINAL_MODULES = {"argparse", "tqdm"}


def cli_only_violations(path: Path) -> list[str]:
    """Argument parsing, printing, terminal streams, exits and the shell itself (a library
    that imports hexhil.cli prints through it) in one file."""
    bad = []
    for node in syntax_nodes(path):
        bad += [f"line {node.lineno}: imports {m}" for m in imported(node)
                if m.split(".")[0] in TERMINAL_MODULES or f"{m}.".startswith(f"{SHELL_MODULE}.")]
        if isinstance(node, ast.ImportFrom) and node.module == "hexhil":
            bad += [f"line {node.lineno}: imports {SHELL_MODULE}" for a in node.names if a.name == "cli"]
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) \
                and node.func.id in ("print", "exit", "quit"):
            bad.append(f"line {node.lineno}: {node.func.id}()")
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) \
                and node.value.id == "sys" and node.attr in ("stdout", "stderr", "exit"):
            bad.append(f"line {node.lineno}: sys.{node.attr}")
        if isinstance(node, ast.Raise) and node.exc is not None and "SystemExit" in ast.unparse(node.exc):
            bad.append(f"line {node.lineno}: raise SystemExit")
    return bad


def _library_modules() -> list[Path]:
    return sorted(p for d in LIBRARY for p in (ROOT / d).rglob("*.py")
                  if not p.relative_to(ROOT).as_posix().startswith(SHELL + "/"))


@pytest.mark.parametrize("path", _library_modules(), ids=lambda p: str(p.relative_to(ROOT)))
def test_only_the_cli_parses_prints_and_exits(path: Path) -> None:
    assert not cli_only_violations(path)


def test_the_cli_checker_sees_a_violation(tmp_path: Path) -> None:
    src = tmp_path / "m.py"
    src.write_text("import sys\nfrom argparse import Namespace\ndef f(x):\n    print(x)\n"
                   "    sys.stderr.write(x)\n    sys.exit(2)\n    raise SystemExit(1)\n"
                   "def g(log):\n    log.info('fine')\n    from hexhil.cli import emit\n"
                   "    from hexhil import cli, run\n")
    assert sorted(cli_only_violations(src)) == [
        "line 10: imports hexhil.cli", "line 11: imports hexhil.cli",
        "line 2: imports argparse", "line 4: print()", "line 5: sys.stderr", "line 6: sys.exit",
        "line 7: raise SystemExit"]


# --- no import circles ------------------------------------------------------------------
# Every import counts, wherever it sits: module level, inside try/if, under ``if
# TYPE_CHECKING:`` (an annotation naming a module's importer is the same knot hidden from the
# interpreter: how hil/world's actuator <-> hexapod circle hid), and inside functions (a
# deferred import defers the loading, not the dependency: two modules that need each other
# are one module in two files). Importing ``a.b.c`` depends on ``a.b.c`` itself, not on the
# packages' ``__init__`` above it; ``from a.b import name`` on ``a.b``, or on ``a.b.name``
# when that is a module.
def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def installed_name(name: str) -> str:
    """A module's name as installed (setup.py FOLDERS): the chip's and the folders' names
    read as the package's, so that one module has one name in the graph."""
    top, dot, rest = name.partition(".")
    if top == "host_tools":
        return f"hexhil{dot}{rest}"
    return f"hexhil.{name}" if top in ("hil", *CHIP_FLOORS) else name


def import_graph(files: list[Path], root: Path) -> dict[str, set[str]]:
    """Project module -> the project modules it imports."""
    names = {installed_name(module_name(p, root)): p for p in files}
    graph: dict[str, set[str]] = {}
    for name, path in names.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        deps: set[str] = set()
        for node in syntax_nodes(path):
            if not isinstance(node, (ast.Import, ast.ImportFrom)):
                continue
            if isinstance(node, ast.Import):
                targets = [installed_name(a.name) for a in node.names]
            else:
                base = installed_name(node.module or "")
                if node.level:
                    up = package.split(".")[:len(package.split(".")) - node.level + 1]
                    base = ".".join([*up, *([base] if base else [])])
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in names else base
                           for a in node.names]
            for t in targets:
                while t and t not in names:   # "import a.b.c" of a name inside a module
                    t = t.rpartition(".")[0]
                if t and t != name:
                    deps.add(t)
        graph[name] = deps
    return graph


def import_circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Every strongly connected group of more than one module (Tarjan), sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    circles = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                circles.append(sorted(group))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(circles)


def test_no_import_circle_among_project_modules() -> None:
    graph = import_graph(_modules(), ROOT)
    assert len(graph) > 100   # the walker found the project
    assert import_circles(graph) == []


def test_the_circle_finder_sees_a_circle(tmp_path: Path) -> None:
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from pkg import b\n")
    (pkg / "b.py").write_text("import pkg.c\nfrom typing import TYPE_CHECKING\n"
                              "if TYPE_CHECKING:\n    from pkg import d\n")
    (pkg / "c.py").write_text("def f():\n    from pkg.a import thing\n")
    (pkg / "d.py").write_text("try:\n    from . import b\nexcept ImportError:\n    pass\n")
    (pkg / "e.py").write_text("from pkg import a\n")
    files = sorted(pkg.glob("*.py"))
    graph = import_graph(files, tmp_path)
    assert graph["pkg.c"] == {"pkg.a"} and graph["pkg.d"] == {"pkg.b"}
    assert graph["pkg.e"] == {"pkg.a"} and graph["pkg"] == set()
    assert import_circles(graph) == [["pkg.a", "pkg.b", "pkg.c", "pkg.d"]]
    (pkg / "b.py").write_text("import pkg.c\n")
    assert import_circles(import_graph(files, tmp_path)) == [["pkg.a", "pkg.b", "pkg.c"]]
    (pkg / "c.py").write_text("import pkg.e\n")
    assert import_circles(import_graph(files, tmp_path)) == [["pkg.a", "pkg.b", "pkg.c", "pkg.e"]]


# --- names and shape --------------------------------------------------------
# A protocol's variant of a thing lives in a folder named for the thing, one file a protocol
# (hil/servobus/protocols/v2.py, host_tools/dynamixel/decode/v1.py, firmware/servo_bus/v2.py),
# never as a numbered sibling (bus2.py, conformance2.py, test_sdk_pty2.py). A model's name
# may end in digits (ax12.py, xl430.py): a lone digit after a letter is the numbered sibling.
NUMBERED = re.compile(r"(?<![0-9])v?[0-9]$")
HIL_TOP_MAX = 12   # modules at hil/'s top level; the rest in its wings


def numbered_siblings(paths: list[Path]) -> list[str]:
    return sorted(str(p.relative_to(ROOT)) for p in paths
                  if NUMBERED.search(p.stem) and p.stem not in ("v1", "v2"))


def test_no_source_file_is_named_by_a_protocol_number() -> None:
    files = [p for d in (*ALLOWED, "bench", "fuzz", "tests") for p in (ROOT / d).rglob("*.py")]
    files += list((ROOT / "firmware" / "c_sdk").rglob("*.[ch]"))
    assert numbered_siblings(files) == []


def test_the_name_rule_sees_a_numbered_sibling() -> None:
    names = ["bus2", "conformance2", "test_sdk_pty2", "mpy_dynamixel2", "line_v2", "v2", "v1",
             "ax12", "xl430", "mpy_ax12", "test_v2_packets", "xseries_servo"]
    assert [Path(ROOT / f"{n}.py").stem for n in names
            if numbered_siblings([ROOT / f"{n}.py"])] == [
        "bus2", "conformance2", "test_sdk_pty2", "mpy_dynamixel2", "line_v2"]


def test_hil_top_level_is_its_wings() -> None:
    top = sorted(p.name for p in (ROOT / "hil").glob("*.py"))
    assert len(top) <= HIL_TOP_MAX, top


# --- no circle among the C SDK's files -------------------------------------------------
# The same rule for C: one source folder is one link unit; a .c file depends on each other
# .c file of its unit whose non-static functions or globals it names, and on the headers it
# includes; a header on the headers it includes. hal_gpio.c, hal_tick.c and hal_uart.c once
# called each other in a circle; now all three call the board core (hal_board.c), which
# calls only the link.
C_DEFINED = re.compile(r"^(?!static\b|extern\b|typedef\b|struct\b[^(]*;|#)[A-Za-z_][\w \t*]*?"
                       r"\b([A-Za-z_]\w*)\s*(?:\([^;{}]*\)\s*\{|(?:\[[^\]]*\])?\s*(?:=[^;]*)?;)",
                       re.M)
C_COMMENT = re.compile(r"/\*.*?\*/|//[^\n]*|\"(?:\\.|[^\"\\])*\"", re.S)
C_INCLUDE = re.compile(r'^#include\s+"([^"]+)"', re.M)


def c_graph(files: list[Path], root: Path = ROOT) -> dict[str, set[str]]:
    """C file -> the project C files it depends on (see above), names relative to root."""
    texts = {p: C_COMMENT.sub(" ", p.read_text(encoding="utf-8")) for p in files}
    headers = {p.name: p for p in files if p.suffix == ".h"}
    defines: dict[Path, set[str]] = {p: set(C_DEFINED.findall(t)) for p, t in texts.items()
                                     if p.suffix == ".c"}
    graph: dict[str, set[str]] = {}
    for p, text in texts.items():
        deps = {headers[h] for h in C_INCLUDE.findall(p.read_text(encoding="utf-8"))
                if h in headers}
        if p.suffix == ".c":
            names = set(re.findall(r"[A-Za-z_]\w*", text))
            deps |= {q for q, defs in defines.items()
                     if q != p and q.parent == p.parent and defs & names}
        graph[str(p.relative_to(root))] = {str(q.relative_to(root)) for q in deps if q != p}
    return graph


def test_no_circle_among_the_c_sdk_files() -> None:
    graph = c_graph(sorted((ROOT / "firmware" / "c_sdk").rglob("*.[ch]")))
    board = "firmware/c_sdk/src/hal_board.c"
    for user in ("hal_gpio.c", "hal_tick.c", "hal_uart.c"):
        assert board in graph[f"firmware/c_sdk/src/{user}"]     # the walker sees the calls
    assert graph[board] == {"firmware/c_sdk/src/hal_board.h",
                            "firmware/c_sdk/src/hexhil_link.c",
                            "firmware/c_sdk/include/hexhil_link.h"}
    assert import_circles(graph) == []


def test_the_c_walker_sees_a_call_circle(tmp_path: Path) -> None:
    src = tmp_path / "src"
    src.mkdir()
    (src / "a.c").write_text('#include "b.h"\nstatic int helper(void) { return 1; }\n'
                             "int a_get(void)\n{\n    return b_get() + helper();\n}\n")
    (src / "b.h").write_text("int b_get(void);\n")
    (src / "b.c").write_text("/* a_get() in a comment is no call */\nint b_count;\n"
                             "int b_get(void) { return b_count; }\n")
    files = sorted(src.glob("*"))
    assert c_graph(files, tmp_path) == {"src/a.c": {"src/b.h", "src/b.c"}, "src/b.h": set(),
                                        "src/b.c": set()}
    (src / "b.c").write_text("int b_get(void) { return a_get(); }\n")
    assert import_circles(c_graph(files, tmp_path)) == [["src/a.c", "src/b.c"]]
