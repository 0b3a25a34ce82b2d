"""One coverage-guided target under atheris, in a process of its own (libFuzzer ends the
process when it is done or finds a crash): ``fuzz/cov.py`` starts it.

Usage: python -m fuzz.cov_harness TARGET LIBFUZZER_FLAGS... [CORPUS_DIR...]
The code a target exercises is instrumented (its ``code``: our modules, and the parsers
two targets ride on, ``tomllib`` for scenarios and ``mcap`` for traces), so mutations that
get further into it are kept; the rest of the project and the reference implementations
(cantools) are not: instrumenting every module took 3 s of each run's start.
"""
import gc
import sys
import types

import atheris

from fuzz.cov_targets import TARGETS


def instrument(code: tuple[str, ...]) -> None:
    """Every function (and the code nested in it) of the modules named in ``code`` and
    under them."""
    for obj in gc.get_objects():
        if isinstance(obj, types.FunctionType) and any(
                obj.__module__ == name or str(obj.__module__).startswith(name + ".")
                for name in code):
            atheris.instrument_func(obj)


if __name__ == "__main__":
    target = TARGETS[sys.argv[1]]
    instrument(target.code)
    atheris.Setup([sys.argv[0], *sys.argv[2:]], target.one_input)
    atheris.Fuzz()
