"""The compiled cores' shared libraries (``make`` builds them beside their Python modules
with the pinned ziglang's C compiler). A core whose library is missing or unloadable is
``None``, and its module keeps its Python path: the same bits, slower."""
from __future__ import annotations

import ctypes
from pathlib import Path


def load_library(path: Path, keep_gil: bool = False) -> ctypes.CDLL | None:
    """``keep_gil``: calls hold the GIL (``PyDLL``), for a core whose state Python shares."""
    if not path.exists():
        return None
    try:
        return (ctypes.PyDLL if keep_gil else ctypes.CDLL)(str(path))
    except OSError:
        return None
