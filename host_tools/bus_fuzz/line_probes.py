"""The firmware's lines run, counted by probes compiled into its functions.

``sys.settrace`` (CPython 3.11 has no ``sys.monitoring``) slows every line of the process
while it is on, the simulator's as much as the firmware's, and a C trace function as well:
the interpreter leaves its specialised instructions while anything traces. Instead, each
function of the firmware's files gets its code compiled anew from its source with one call
before each statement, ``set.add`` of the statement's number, and the function objects that
exist take the new code (``__code__``); functions made later are made from it. A statement's
lines are those of its own expressions (a compound statement's header: an ``if``'s test, a
``for``'s target and iterable; not its body, whose statements have probes of their own), as
the interpreter's line events would name them. A frame running when the probes go in keeps
its code, so they go in before the firmware starts (the fork server: as the run is built),
and a forked child forgets the boot's lines (``reset``). A statement's probe runs before it:
one that raises counts its lines all the same. Module and class bodies run at import,
before any run: they have none.
"""
from __future__ import annotations

import ast
import gc
import os
import types
from pathlib import Path
from typing import Iterator, Sequence

PROBE = "__hexhil_line__"      # the probe's name in each probed module's globals
_SCOPES = (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)
_BODIES = ("body", "orelse", "finalbody", "handlers", "cases")
_HITS: set[int] = set()                          # the probes that ran since ``reset``
_TABLE: list[tuple[str, tuple[int, ...]]] = []   # a probe's file name and lines


def install(roots: Sequence[Path]) -> None:
    """Every live function of a file under ``roots`` takes its code with probes (once a
    process: a function probed already is left as it is). Before the firmware runs, so that
    its main loop's frame, running at the fork, has them too."""
    prefixes = tuple(str(r) + os.sep for r in roots)
    by_file: dict[str, list[types.FunctionType]] = {}
    for obj in gc.get_objects():
        if (type(obj) is types.FunctionType and PROBE not in obj.__code__.co_names
                and obj.__code__.co_filename.startswith(prefixes)):
            by_file.setdefault(obj.__code__.co_filename, []).append(obj)
    for filename, functions in sorted(by_file.items()):
        try:
            tree = ast.parse(Path(filename).read_text(encoding="utf-8"), filename)
        except (OSError, SyntaxError, ValueError):
            continue               # no source to compile anew: left unprobed
        name = Path(filename).name
        for scope in ast.walk(tree):
            if isinstance(scope, (ast.FunctionDef, ast.AsyncFunctionDef)):
                _probe_bodies(scope, name, first=True)
            elif isinstance(scope, ast.Lambda):      # lambda x: PROBE(k) or body
                scope.body = _before(scope.body, set(_lines(scope.body)), name)
        codes = {(c.co_qualname, c.co_firstlineno): c
                 for c in _codes(compile(tree, filename, "exec", dont_inherit=True))}
        for f in functions:
            new = codes.get((f.__code__.co_qualname, f.__code__.co_firstlineno))
            if new is not None and new.co_freevars == f.__code__.co_freevars:
                f.__globals__[PROBE] = _HITS.add
                f.__code__ = new


def reset() -> None:
    """Forget the lines run so far (a forked child: the boot's)."""
    _HITS.clear()


def lines() -> set[tuple[str, int]]:
    """The (file name, line) pairs run since ``reset``."""
    return {(_TABLE[k][0], n) for k in _HITS for n in _TABLE[k][1]}


def _probe_bodies(node: ast.AST, name: str, first: bool = False) -> None:
    """A probe before each statement of each body of ``node``, and so on down, not into a
    nested scope (``ast.walk`` brings each function to ``install`` on its own). A loop's
    header runs again before each pass, a bare ``except:`` when it catches: their lines go
    in the probe of their body's first statement; an ``except T:`` probes in its test."""
    for field in _BODIES:
        body = getattr(node, field, None)
        if not body:
            continue
        if field in ("handlers", "cases"):
            for part in body:        # except (PROBE(k) or T): counts when T is tested
                if isinstance(part, ast.ExceptHandler) and part.type is not None:
                    part.type = _before(part.type, {part.lineno, *_lines(part.type)}, name)
                _probe_bodies(part, name)
            continue
        head: set[int] = set()
        if field == "body" and isinstance(node, (ast.While, ast.For, ast.AsyncFor)):
            head = set(_lines(node))
        elif field == "body" and isinstance(node, ast.ExceptHandler) and node.type is None:
            head = {node.lineno}
        out: list[ast.stmt] = []
        for i, stmt in enumerate(body):
            docstring = (first and i == 0 and isinstance(stmt, ast.Expr)
                         and isinstance(stmt.value, ast.Constant)
                         and isinstance(stmt.value.value, str))
            if not docstring and not isinstance(stmt, (ast.Global, ast.Nonlocal)):
                probe = _probe(head | set(_lines(stmt)), name, stmt)
                out.append(ast.copy_location(ast.Expr(probe), stmt))
                head = set()
            out.append(stmt)
            if not isinstance(stmt, _SCOPES):
                _probe_bodies(stmt, name)
        setattr(node, field, out)


def _before(expr: ast.expr, lines: set[int], name: str) -> ast.BoolOp:
    """``PROBE(k) or expr``: the probe returns None, so the value is ``expr``'s."""
    return ast.copy_location(ast.BoolOp(ast.Or(), [_probe(lines, name, expr), expr]), expr)


def _probe(lines: set[int], name: str, at: ast.AST) -> ast.Call:
    """``PROBE(k)``, the ``k``th probe, counting ``lines`` of file ``name``, placed at
    ``at`` (its line numbers: tracebacks and line events stay as they were)."""
    _TABLE.append((name, tuple(sorted(lines))))
    call = ast.Call(ast.Name(PROBE, ast.Load()), [ast.Constant(len(_TABLE) - 1)], [])
    return ast.fix_missing_locations(ast.copy_location(call, at))


def _lines(node: ast.AST) -> Iterator[int]:
    """The lines of a statement's own expressions: not its bodies', nor a nested scope's."""
    if isinstance(node, ast.stmt | ast.expr) and not isinstance(node, ast.Lambda):
        yield node.lineno
    if isinstance(node, _SCOPES):
        for d in getattr(node, "decorator_list", ()):
            yield from _lines(d)
        return
    for field, value in ast.iter_fields(node):
        if field in _BODIES:
            continue
        for child in value if isinstance(value, list) else [value]:
            if isinstance(child, ast.AST):
                yield from _lines(child)


def _codes(code: types.CodeType) -> Iterator[types.CodeType]:
    """A code object and every one nested in its constants."""
    yield code
    for c in code.co_consts:
        if isinstance(c, types.CodeType):
            yield from _codes(c)
