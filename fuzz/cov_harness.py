"""One coverage-guided target under atheris, in a process of its own (libFuzzer ends the
process when it is done or finds a crash): ``fuzz/cov.py`` starts it.

Usage: python -m fuzz.cov_harness TARGET LIBFUZZER_FLAGS... [CORPUS_DIR...]
Every module of the project is instrumented, and the parsers two targets ride on
(``tomllib`` for scenarios, ``mcap`` for traces) so mutations that get further into the
file are kept; the reference implementations (cantools) are not.
"""
import sys

import atheris

INSTRUMENTED = ["hexhil", "tomllib", "mcap"]

with atheris.instrument_imports(include=INSTRUMENTED):
    from fuzz.cov_targets import TARGETS

if __name__ == "__main__":
    target = TARGETS[sys.argv[1]]
    atheris.Setup([sys.argv[0], *sys.argv[2:]], target.one_input)
    atheris.Fuzz()
