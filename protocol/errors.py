"""The errors a user can act on: a one-line message, never a traceback.

``UserError`` is the base; its kinds are also the built-in error a Python caller already
catches: ``BadValue`` is a ``ValueError`` (a key, number or argument outside its rules, a
file whose contents are not what they must be), ``BadFile`` an ``OSError`` (a path that
cannot be read or written, a program, device or address that is not there), ``TimedOut`` a
``TimeoutError`` (a client, a scheduler or a firmware that did not come in its time). Exit
statuses are the
command line's alone (host_tools/cli/). They live at the bottom floor so that the simulator
(hil/) and the host tools raise the same types; MicroPython-compatible like the rest of
protocol/: MicroPython cannot derive from two built-in exceptions, so there the kinds are
``UserError``s only.
"""
import sys


class UserError(Exception):
    """Bad input from the user (file, argument, scenario key, corrupt trace).

    The message speaks the API's terms: ``params`` are the API parameters it names, as
    written in it (``duration_s``); the CLI writes them as its flags (``--duration``).
    """

    def __init__(self, message, params=()):
        super().__init__(message)
        self.params = tuple(params)

    def __str__(self):
        return self.args[0] if self.args else ""


if sys.implementation.name == "micropython":
    class BadValue(UserError):
        pass

    class BadFile(UserError):
        pass

    class TimedOut(UserError):
        pass
else:
    class BadValue(UserError, ValueError):
        """A value outside its rules: a scenario key, a number, an argument, a file's contents."""

    class BadFile(UserError, OSError):
        """A path that cannot be read or written, a program or device that is not there."""

    class TimedOut(UserError, TimeoutError):
        """Something the run waits for (a client, a scheduler, the firmware) did not come in
        its time."""
