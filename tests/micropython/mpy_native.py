# protocol/native.py under the real micropython binary: @micropython.native compiles to machine
# code there and is the identity under CPython; the float results are the bytecode's, bit for bit.
import math
import struct
import sys

from protocol.native import micropython
from tests.micropython.checks import check, done


def ik_like(x, y, z):
    r = math.sqrt(x * x + y * y) - 0.05
    d = math.sqrt(r * r + z * z)
    a = (0.082 * 0.082 + d * d - 0.12 * 0.12) / (2 * 0.082 * d)
    return math.atan2(z, r) + math.acos(a), round(math.degrees(d) * 1023 / 300.0)


@micropython.native
def ik_like_native(x, y, z):
    r = math.sqrt(x * x + y * y) - 0.05
    d = math.sqrt(r * r + z * z)
    a = (0.082 * 0.082 + d * d - 0.12 * 0.12) / (2 * 0.082 * d)
    return math.atan2(z, r) + math.acos(a), round(math.degrees(d) * 1023 / 300.0)


check(hasattr(micropython, "const") == (sys.implementation.name == "micropython"),
      "the real module under MicroPython, the stand-in under CPython")
for k in range(50):
    p = (0.11 + k * 0.0017, 0.02 - k * 0.0009, -0.085 + k * 0.0013)
    want, got = ik_like(*p), ik_like_native(*p)
    check(struct.pack("<d", want[0]) == struct.pack("<d", got[0]) and want[1] == got[1],
          "native float bits %d" % k)
done("native")
