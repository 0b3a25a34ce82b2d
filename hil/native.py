"""The compiled cores' shared libraries, built by the package (setup.py's ``build_ext``,
on ``pip install .`` or ``pip install -e .``) beside their Python modules. A core whose
library is missing or unloadable is ``None``, and its module keeps its Python path: the
same bits, slower; the first such load logs one warning line, so it is never silent."""
from __future__ import annotations

import ctypes
import logging
from pathlib import Path

log = logging.getLogger(__name__)

_HIL = Path(__file__).parent
# what each core is, to a user -> its library (the names setup.py builds)
CORES: dict[str, Path] = {
    "drive bank": _HIL / "world" / "_drive_core.so",
    "servo bank and reads": _HIL / "servobus" / "_servo_core.so",
    "ELF board": _HIL / "mcu" / "_board_core.so",
}
REBUILD = "pip install -e . (or make) builds it"
_warned: set[Path] = set()


def load_library(path: Path, keep_gil: bool = False) -> ctypes.CDLL | None:
    """``keep_gil``: calls hold the GIL (``PyDLL``), for a core whose state Python shares."""
    try:
        return (ctypes.PyDLL if keep_gil else ctypes.CDLL)(str(path))
    except OSError as exc:
        if path not in _warned:
            _warned.add(path)
            why = "not built" if not path.exists() else f"not loadable ({exc})"
            log.warning("compiled core %s is %s: its Python path runs, slower; %s",
                        path.name, why, REBUILD)
        return None


def compiled() -> dict[str, str]:
    """Each core's state, for ``hexhil --version``: its library's path, else why not."""
    state = {}
    for name, path in CORES.items():
        try:
            ctypes.CDLL(str(path))
            state[name] = f"compiled ({path})"
        except OSError as exc:
            state[name] = "not built" if not path.exists() else f"not loadable: {exc}"
    return state
