"""How long library work (a sweep's runs, training epochs, rendered frames) reports its
progress: through a callback its caller passes. The ``hexhil`` command draws it as a
progress bar on stderr; a script may log it or pass nothing (silent)."""
from __future__ import annotations

from typing import Protocol


class Progress(Protocol):
    """Called with 0 done when a stage starts, then after each unit of work; ``note`` is a
    short running figure (e.g. the latest loss)."""

    def __call__(self, desc: str, done: int, total: int, note: str = "") -> None: ...


def report(progress: Progress | None, desc: str, done: int, total: int, note: str = "") -> None:
    """Call ``progress`` if there is one: the one place that checks for a silent caller."""
    if progress is not None:
        progress(desc, done, total, note)
