"""The one error type a user sees: a one-line message and exit status 2, never a traceback.

It lives at the bottom floor so that the simulator (hil/) and the host tools raise the same
type; MicroPython-compatible like the rest of protocol/.
"""


class UserError(Exception):
    """Bad input from the user (file, flag, scenario key, corrupt trace).

    The CLI prints ``hexhil: <message>`` on stderr and exits with ``code``.
    """

    def __init__(self, message, code=2):
        super().__init__(message)
        self.code = code
