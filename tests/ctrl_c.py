"""For the tests that press Ctrl-C on a child ``hexhil`` (SIGINT): the child's default SIGINT
back, as a ``preexec_fn``. A shell that starts a job in the background without job control
(``make test &``) starts it with SIGINT ignored, every child inherits that, and a Python
started so installs no KeyboardInterrupt handler: the signal would do nothing."""
from __future__ import annotations

import signal


def sigint_default() -> None:
    """``preexec_fn`` of a child that must stop on SIGINT as at a terminal."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
