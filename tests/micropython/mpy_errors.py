# protocol/errors.py under the real micropython binary: the user errors, their kinds UserErrors.
from protocol.errors import BadFile, BadValue, TimedOut, UserError
from tests.micropython.checks import check, done, raises


def bad():
    raise UserError("scenario.toml: key 'bus.baud' must be positive")


raises(bad, UserError, "UserError not raised")
raises(bad, Exception, "UserError is not an Exception")
try:
    bad()
except UserError as exc:
    check(str(exc) == "scenario.toml: key 'bus.baud' must be positive", "message kept")
check(all(isinstance(kind("x"), UserError) for kind in (BadValue, BadFile, TimedOut)), "kinds")
check(str(BadValue("v", ["a"])) == "v" and BadValue("v", ["a"]).params == ("a",), "a kind's fields")
check(UserError("x").params == (), "no parameters named")
check(UserError("rate must be >= 0", params=["rate"]).params == ("rate",), "parameters kept")
done("errors")
