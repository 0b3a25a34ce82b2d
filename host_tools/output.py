"""A result file hexhil writes after its work (a video, a figure, a JUnit report): checked
before the work starts, so that a typo in its folder costs one line, not a sweep's minutes.
(Traces have their own: host_tools/trace/target.py.)"""
from __future__ import annotations

import os
from pathlib import Path

from hexhil.protocol.errors import BadFile


def check_output(path: str | Path, param: str, overwrite: bool = True) -> Path:
    """``path`` as an output file: its folder exists and is writable, it is not a folder,
    and it does not exist yet unless ``overwrite``; ``UserError`` naming ``param``. A
    device (``/dev/null``) is taken as it is."""
    p = Path(path)
    if p.is_dir():
        raise BadFile(f"{param} {p}: is a directory, not a file", params=(param,))
    if p.exists() and not p.is_file():
        return p
    folder = p.parent
    if not folder.is_dir():
        raise BadFile(f"{param} {p}: no such directory {folder}", params=(param,))
    if p.exists() and not overwrite:
        raise BadFile(f"{param} {p} exists: pass overwrite to replace it",
                      params=(param, "overwrite"))
    if not os.access(p if p.exists() else folder, os.W_OK):
        raise BadFile(f"{param} {p}: not writable here", params=(param,))
    return p


def write_failed(path: str | Path, param: str, exc: OSError) -> BadFile:
    """The one line for a write that failed after the work (a full disk, ``/dev/full``)."""
    return BadFile(f"{param} {path}: cannot write it ({exc.strerror or exc})",
                   params=(param,))
