"""The one lifecycle of everything in the API that runs something (``Run``,
``RealTimeRun``): made, run once, closed. ``close()`` is safe to call again and on an
object whose start failed; ``with`` calls it on the way out, whatever happened. A Ctrl-C
ends a run however it is reported on its way out (``ctrl_c_behind``)."""
from __future__ import annotations

from typing import Any, TypeVar

T = TypeVar("T", bound="Closing")


def ctrl_c_behind(exc: BaseException | None) -> KeyboardInterrupt | None:
    """The Ctrl-C that ``exc`` came from, or None: a clean-up that failed while it unwound
    (a ``finally`` on a half-done state), an import that it cut short (MuJoCo's)."""
    while exc is not None and not isinstance(exc, KeyboardInterrupt):
        exc = exc.__cause__ or exc.__context__
    return exc


class Closing:
    """A context manager over the subclass's ``close()``."""

    def close(self) -> None:
        raise NotImplementedError

    def __enter__(self: T) -> T:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
