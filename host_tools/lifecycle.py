"""The one lifecycle of everything in the API that runs something (``Run``,
``RealTimeRun``): made, run once, closed. ``close()`` is safe to call again and on an
object whose start failed; ``with`` calls it on the way out, whatever happened."""
from __future__ import annotations

from typing import Any, TypeVar

T = TypeVar("T", bound="Closing")


class Closing:
    """A context manager over the subclass's ``close()``."""

    def close(self) -> None:
        raise NotImplementedError

    def __enter__(self: T) -> T:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
