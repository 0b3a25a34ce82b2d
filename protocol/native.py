"""``micropython.native`` and ``viper`` under both interpreters, for the firmware's hottest
functions.

MicroPython's compiler reads ``@micropython.native`` by its name and emits machine code for
the function: the same runtime calls as its bytecode (every float operation included, so
the same bits), without the bytecode's dispatch. A module writes
``from protocol.native import micropython``: under MicroPython that is the real module;
under CPython, which has no such emitter, ``native`` returns the function unchanged.
Machine code needs a target: ``mpy-cross -march=x64`` on this host, ``-march=armv7emsp``
for the STM32F411 board. ``@micropython.viper`` (with ``ptr8``, a byte pointer) does its
integer arithmetic in machine words: only for byte loops whose values stay small, never for
floats.
"""
import sys

if sys.implementation.name == "micropython":
    import micropython

    ptr8 = None   # viper compiles ptr8(buf) itself; the name is here for the import
else:  # not an ImportError test: tests/micropython/ is a package named micropython
    class micropython:  # noqa: N801 - stands in for the module of that name
        """CPython: the emitter decorators leave a function as it is."""

        @staticmethod
        def native(fn):
            return fn

        viper = native

    def ptr8(buf):
        """Viper's byte pointer; CPython indexes the buffer itself."""
        return buf
