"""Stand-in for MicroPython's ``time`` on the virtual board: virtual time (vboard.py).

Each ``ticks_*`` call costs vboard.QUANTUM_US (the busy-wait rule); sleeps jump to their
end through the host. The real module, for wall-clock profiling, is ``utime``.
"""
import vboard

_MASK = vboard.TICKS_PERIOD - 1
_HALF = vboard.TICKS_PERIOD // 2


def ticks_us():
    b = vboard.board()
    b.poll()
    return b.now_us & _MASK


def ticks_ms():
    b = vboard.board()
    b.poll()
    return (b.now_us // 1000) & _MASK


def ticks_diff(a, b):
    return ((a - b + _HALF) & _MASK) - _HALF


def ticks_add(a, delta):
    return (a + delta) & _MASK


def sleep_us(us):
    b = vboard.board()
    b.sleep_until(b.now_us + int(us))


def sleep_ms(ms):
    sleep_us(int(ms) * 1000)


def sleep(s):
    sleep_us(int(s * 1000000))


def time():
    """Whole seconds since the run started (the board has no calendar)."""
    return vboard.board().now_us // 1000000


def time_ns():
    return vboard.board().now_us * 1000
