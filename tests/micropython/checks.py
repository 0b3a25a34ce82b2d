# The protocol scripts' one assert helper, the same under micropython and CPython: check()
# raises with what failed and counts what passed; done() prints the closing line the pytest
# side reads, "OK <module> <checks>".
_passed = [0]


def check(cond, what):
    if not cond:
        raise AssertionError(what)
    _passed[0] += 1


def done(module):
    print("OK", module, _passed[0])


def raises(fn, exc, what):
    try:
        fn()
    except exc:
        _passed[0] += 1
    else:
        raise AssertionError(what)
