"""The fuzzer's line probes (host_tools/bus_fuzz/line_probes.py) count the lines that
``sys.settrace`` reports, in functions that loop, branch, raise and catch, span lines and
make closures."""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from typing import Any

from hexhil.bus_fuzz import line_probes

SOURCE = '''
def run(n):
    """A docstring: no line of its own."""
    total, seen = 0, []
    i = 0
    while i < n:
        i += 1
        if i % 3 == 0:
            continue
        elif i % 5 == 0:
            total += helper(i,
                            seen)
        else:
            seen.append(
                i)
    for k in range(2):
        try:
            if k:
                raise KeyError(k)
        except ValueError:
            total = -1
        except (KeyError,
                IndexError):
            total += 100
        finally:
            total += 1
    try:
        helper(None, None)
    except:
        total += 0
    square = (lambda x:
              x * x)
    def inner(y):
        return square(y) + total
    return inner(2) if total > 0 else [j
                                       for j in seen]


def helper(a, b):
    b.append(a)
    return a * 2


def never():
    return 0
'''


def _load(folder: Path) -> Any:
    path = folder / "probed_sample.py"
    path.write_text(SOURCE)
    spec = importlib.util.spec_from_file_location("probed_sample", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _traced(module: Any, n: int) -> set[tuple[str, int]]:
    hits: set[tuple[str, int]] = set()
    filename = module.__file__

    def trace(frame: Any, event: str, arg: Any) -> Any:
        if frame.f_code.co_filename != filename:
            return None
        if event == "line":
            hits.add((Path(filename).name, frame.f_lineno))
        return trace

    sys.settrace(trace)
    try:
        module.run(n)
    finally:
        sys.settrace(None)
    return hits


def test_the_probes_count_the_lines_settrace_reports(tmp_path: Path) -> None:
    module = _load(tmp_path)
    want = {n: _traced(module, n) for n in (0, 4, 11)}
    line_probes.install([tmp_path])
    assert line_probes.PROBE in module.run.__code__.co_names
    for n, lines in want.items():
        line_probes.reset()
        assert module.run(n) == _load_free_result(n)
        assert line_probes.lines() == lines, n
    line_probes.install([tmp_path])                 # once a process: no second probe
    line_probes.reset()
    module.run(4)
    assert line_probes.lines() == want[4]


def _load_free_result(n: int) -> Any:
    """What ``run(n)`` returns unprobed: the probes change no result."""
    namespace: dict[str, Any] = {}
    exec(compile(SOURCE, "<unprobed>", "exec"), namespace)
    return namespace["run"](n)
