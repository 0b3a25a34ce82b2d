"""The firmware's own import names inside the host's interpreter.

On the chip (and under the ``micropython`` binary) ``protocol/`` and ``firmware/`` sit at
the top of the filesystem, so the firmware writes ``from protocol import sim_link``. The
package installs them as ``hexhil.protocol`` and ``hexhil.firmware``, so that no generic
top-level name is taken from other projects. A module of those two packages, or a firmware
file the host loads (``load_main``), is executed with an ``__import__`` of its own that
reads ``protocol...`` and ``firmware...`` as the installed names: the same module objects
the host imports, and nothing added to ``sys.modules`` under the bare names.
"""
from __future__ import annotations

import builtins
import importlib.abc
import importlib.machinery
import sys
from types import ModuleType
from typing import Any, Sequence

PACKAGE = __name__.rpartition(".")[0]                       # "hexhil"
CHIP_TOPS = ("protocol", "firmware")                         # the chip's top-level folders
_PREFIXES = tuple(f"{PACKAGE}.{top}" for top in CHIP_TOPS)


def _chip_import(name: str, globals: dict | None = None, locals: dict | None = None,
                 fromlist: Sequence[str] = (), level: int = 0) -> ModuleType:
    top = name.partition(".")[0]
    if level or top not in CHIP_TOPS:
        return builtins.__import__(name, globals, locals, fromlist, level)
    module = builtins.__import__(f"{PACKAGE}.{name}", globals, locals, fromlist, 0)
    # ``import protocol.x`` binds ``protocol``; ``from protocol.x import y`` reads protocol.x
    return module if fromlist else sys.modules[f"{PACKAGE}.{top}"]


CHIP_BUILTINS: dict[str, Any] = {**vars(builtins), "__import__": _chip_import}


def chip_module(module: ModuleType) -> ModuleType:
    """``module`` (not yet executed) made to import as the firmware does on the chip."""
    module.__dict__["__builtins__"] = CHIP_BUILTINS
    return module


class _ChipLoader(importlib.machinery.SourceFileLoader):
    def exec_module(self, module: ModuleType) -> None:
        super().exec_module(chip_module(module))


class _ChipFinder(importlib.abc.MetaPathFinder):
    """Finds ``hexhil.protocol...`` and ``hexhil.firmware...`` as the other finders do,
    loading their sources with the chip's import names."""

    def find_spec(self, fullname: str, path: Any = None, target: Any = None) -> Any:
        if not (fullname in _PREFIXES or fullname.startswith(tuple(p + "." for p in _PREFIXES))):
            return None
        for finder in sys.meta_path:
            if finder is self or not hasattr(finder, "find_spec"):
                continue
            spec = finder.find_spec(fullname, path, target)
            if spec is not None:
                if type(spec.loader) is importlib.machinery.SourceFileLoader:
                    spec.loader = _ChipLoader(spec.loader.name, spec.loader.path)
                return spec
        return None


def install() -> None:
    """Put the finder first, once per interpreter."""
    if not any(isinstance(f, _ChipFinder) for f in sys.meta_path):
        sys.meta_path.insert(0, _ChipFinder())
