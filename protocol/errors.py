"""The one error type a user sees: a one-line message and exit status 2, never a traceback.

It lives at the bottom floor so that the simulator (hil/) and the host tools raise the same
type; MicroPython-compatible like the rest of protocol/.
"""


class UserError(Exception):
    """Bad input from the user (file, argument, scenario key, corrupt trace).

    The message speaks the API's terms: ``params`` are the API parameters it names, as
    written in it (``duration_s``); the CLI writes them as its flags (``--duration``),
    prints ``hexhil: <message>`` on stderr and exits with ``code``.
    """

    def __init__(self, message, code=2, params=()):
        super().__init__(message)
        self.code = code
        self.params = tuple(params)
