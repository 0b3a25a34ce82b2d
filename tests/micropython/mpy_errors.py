# protocol/errors.py under the real micropython binary: the one user-error type.
from protocol.errors import UserError
from tests.micropython.checks import check, done, raises


def bad():
    raise UserError("scenario.toml: key 'bus.baud' must be positive")


raises(bad, UserError, "UserError not raised")
raises(bad, Exception, "UserError is not an Exception")
try:
    bad()
except UserError as exc:
    check(str(exc) == "scenario.toml: key 'bus.baud' must be positive", "message kept")
    check(exc.code == 2, "default exit status 2")
check(UserError("x", 3).code == 3, "exit status given")
check(UserError("x").params == (), "no parameters named")
check(UserError("rate must be >= 0", params=["rate"]).params == ("rate",), "parameters kept")
done("errors")
