"""The HAL contract: everything the firmware (controller.py, main.py, telemetry.py,
commands.py) uses of a board, declared once. Every back end subclasses ``Board`` and
``CAN`` (hal/sim.py: the simulator link; hal/serial.py: a tty under the unix port;
hal/board.py: the STM32); tests/test_hal_contract.py runs one contract test on every back
end the host can run. MicroPython-compatible (no typing, no abc).

A board has:
  ``uart``       ``write(buf, n)`` (no reply expected), ``transact(buf, n, rx, nrx,
                 timeout_us)`` -> bytes received into ``rx`` (half duplex, bus-time timeout)
  ``switches``   six objects, leg order LF LM LH RF RM RH; ``value()`` 1 pressed, 0 not
  ``can``        a ``CAN``: ``send(data, arb_id)``, ``any()``, ``recv()`` -> (arb_id, bytes)
  ``ended``      True once the run is over: the control loop exits
and the methods below. The control clock is ``ticks_us`` with ``ticks_diff``/``ticks_add``
(it may wrap, as MicroPython's does); ``perf_us`` and ``io_us`` are for profiling only.
"""
import time


class CAN:
    """A classic CAN port; frames for the firmware wait in ``rxq``, oldest first. This
    base has no controller: a sent frame is counted in ``dropped`` and none arrive."""

    def __init__(self):
        self.dropped = 0
        self.rxq = []

    def send(self, data, arb_id):
        """Send ``data`` (<= 8 bytes) with standard ID ``arb_id`` (pyb.CAN's order)."""
        self.dropped += 1

    def any(self):
        return len(self.rxq) > 0

    def recv(self):
        """(arb_id, data bytes) of the oldest received frame."""
        return self.rxq.pop(0)


class Switch:
    """A limit switch whose level the back end keeps in ``board.switch_bits`` (bit
    ``index``): sampled by the host at each sleep, or read from a sensor node."""

    def __init__(self, board, index):
        self.board = board
        self.bit = 1 << index

    def value(self):
        return 1 if self.board.switch_bits & self.bit else 0


class Board:
    """The contract's defaults: the wall clock (``time.ticks_*``), no host to wait on, no
    config overrides, events printed on stdout (``event <kind> <text>``)."""

    ended = False

    def ticks_us(self):
        return time.ticks_us()

    def ticks_diff(self, a, b):
        return time.ticks_diff(a, b)

    def ticks_add(self, a, dt):
        return time.ticks_add(a, dt)

    def sleep_until(self, t_us):
        """End of a cycle: return at ``t_us`` with the switches and CAN input fresh."""
        dt = time.ticks_diff(t_us, time.ticks_us())
        if dt > 0:
            time.sleep_us(dt)

    def perf_us(self):
        """Wall-clock microseconds (profiling only, never for control)."""
        return time.ticks_us()

    def io_us(self):
        """Wall time spent waiting on a host so far (profiling; 0 without one)."""
        return 0

    def config(self):
        """Overrides of firmware/config.py (keys: protocol/link_schema.py CONFIG)."""
        return {}

    def event(self, kind, text):
        """A protocol/sim_link.py event (kind EVENT_*, text or JSON)."""
        print("event", kind, text)

    def close(self):
        """The run is over: release what the board holds."""
