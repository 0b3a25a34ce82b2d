"""A compiled library's struct checked against the ``ctypes.Structure`` that restates it.

The board core (board_core.c) and its Python side share one struct, ``bc_t``, which Python
reads and writes as ``Shared`` (board_core.py). The library says how its compiler laid the
struct out (``bc_layout``: each field's name, offset and size, and the whole size); a
library built from another board_core.c is refused, never read with the wrong offsets.
"""
from __future__ import annotations

import ctypes
from typing import Any


def layout_mismatch(lib: Any, structure: type[ctypes.Structure]) -> str | None:
    """How ``lib``'s struct differs from ``structure`` (the first difference, in words), or
    None when every field has the same offset and size and the struct the same size."""
    fn = lib.bc_layout
    fn.restype = ctypes.c_int32
    fn.argtypes = [ctypes.c_int32, ctypes.POINTER(ctypes.c_char_p),
                   ctypes.POINTER(ctypes.c_int64), ctypes.POINTER(ctypes.c_int64)]
    name, offset, size = ctypes.c_char_p(), ctypes.c_int64(), ctypes.c_int64()
    fn(-1, ctypes.byref(name), ctypes.byref(offset), ctypes.byref(size))
    if size.value != ctypes.sizeof(structure):
        return f"bc_t is {size.value} bytes there, {structure.__name__} " \
               f"{ctypes.sizeof(structure)}"
    seen = set()
    i = 0
    while fn(i, ctypes.byref(name), ctypes.byref(offset), ctypes.byref(size)):
        field = name.value.decode()
        mine = getattr(structure, field, None)
        if mine is None:
            return f"bc_t has {field}, {structure.__name__} has not"
        if (mine.offset, mine.size) != (offset.value, size.value):
            return (f"{field} is at {offset.value} ({size.value} bytes) there, at "
                    f"{mine.offset} ({mine.size} bytes) in {structure.__name__}")
        seen.add(field)
        i += 1
    missing = [f[0] for f in structure._fields_ if f[0] not in seen]
    return f"bc_t has no {missing[0]}" if missing else None
