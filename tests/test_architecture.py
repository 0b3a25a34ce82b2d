"""The floors hold: protocol/ at the bottom, firmware/ and hil/ on it and never on each
other, host_tools/ on top; and no source file grows past 500 lines."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
# What each floor may import from the project (its own floor included).
ALLOWED = {
    "protocol": {"protocol"},
    "firmware": {"protocol", "firmware"},
    "hil": {"protocol", "hil"},
    "host_tools": {"protocol", "hil", "host_tools"},
}
# host_tools/ stands on firmware/ too, but only here: the in-process runtime runs the
# firmware in the host (issue 18); every other host tool meets it through the link.
FIRMWARE_RUNNERS = {"host_tools/in_process.py"}
PACKAGES = set(ALLOWED)
MAX_LINES = 500


def _modules() -> list[Path]:
    return sorted(p for d in ALLOWED for p in (ROOT / d).rglob("*.py"))


def project_imports(path: Path) -> list[tuple[int, str]]:
    """(line, top-level package) of every project import in a file, nested ones too."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module]
        out += [(node.lineno, n.split(".")[0]) for n in names if n.split(".")[0] in PACKAGES]
    return out


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(ROOT)))
def test_imports_stay_on_or_below_their_floor(path: Path) -> None:
    rel = path.relative_to(ROOT)
    floor = rel.parts[0]
    allowed = ALLOWED[floor] | ({"firmware"} if rel.as_posix() in FIRMWARE_RUNNERS else set())
    bad = [f"line {line}: {floor} imports {pkg}" for line, pkg in project_imports(path)
           if pkg not in allowed]
    assert not bad, bad


def test_the_walker_sees_a_violation(tmp_path: Path) -> None:
    src = tmp_path / "m.py"
    src.write_text("import os\ndef f():\n    from firmware import config\nfrom hil.bus import Bus\n")
    assert sorted(project_imports(src)) == [(3, "firmware"), (4, "hil")]


def test_no_source_file_over_500_lines() -> None:
    files = [p for d in (*ALLOWED, "bench", "fuzz", "tests") for p in (ROOT / d).rglob("*.py")]
    long = {str(p.relative_to(ROOT)): n for p in files
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_LINES}
    assert not long, long
