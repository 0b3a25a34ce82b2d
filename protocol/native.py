"""``micropython.native`` under both interpreters, for the firmware's hottest functions.

MicroPython's compiler reads ``@micropython.native`` by its name and emits machine code for
the function: the same runtime calls as its bytecode (every float operation included, so
the same bits), without the bytecode's dispatch. A module writes
``from protocol.native import micropython``: under MicroPython that is the real module;
under CPython, which has no such emitter, ``native`` returns the function unchanged.
Machine code needs a target: ``mpy-cross -march=x64`` on this host, ``-march=armv7emsp``
for the STM32F411 board. (Viper, the other emitter, does integer arithmetic in machine
words: not used.)
"""
import sys

if sys.implementation.name == "micropython":
    import micropython
else:  # not an ImportError test: tests/micropython/ is a package named micropython
    class micropython:  # noqa: N801 - stands in for the module of that name
        """CPython: the emitter decorators leave a function as it is."""

        @staticmethod
        def native(fn):
            return fn
