"""The one error type a user sees: a one-line message and exit status 2, never a traceback."""


class UserError(Exception):
    """Bad input from the user (file, flag, scenario key, corrupt trace).

    The CLI prints ``hexhil: <message>`` on stderr and exits with ``code``.
    """

    def __init__(self, message: str, code: int = 2) -> None:
        super().__init__(message)
        self.code = code
