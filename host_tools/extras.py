"""The optional dependencies (pyproject.toml's extras) and the one line that says how to get
one: torch (the GRNN) and distributed (Dask sweeps) are heavy and needed by few."""
from __future__ import annotations

import importlib

from hexhil.protocol.errors import BadFile

# module -> (extra that installs it, what needs it)
EXTRAS: dict[str, tuple[str, str]] = {
    "torch": ("grnn", "the GRNN (hexhil grnn, hexhil run --navigator grnn)"),
    "distributed": ("dask", "a Dask cluster (--scheduler)"),
}


def require(module: str) -> None:
    """Import ``module`` (one of ``EXTRAS``) or refuse in one line naming its extra."""
    try:
        importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name != module:      # installed, but broken underneath: not ours to explain
            raise
        extra, needed_for = EXTRAS[module]
        raise BadFile(f"{needed_for} needs {module}, an optional dependency: "
                      f"pip install 'hexhil[{extra}]'") from None
