"""What the board and serial back ends share: the half-duplex servo transaction (their
wall-clock timing is hal/base.py ``Board``'s).

``HalfDuplexUART`` drives any UART-like object (``write``, ``any``, ``read``, ``readinto``:
``machine.UART`` on the board, hal/serial.py's tty on the unix port) with an optional
direction pin (the board's 74HC126/74HC04 circuit). MicroPython-compatible.
"""
import time


class HalfDuplexUART:
    """``write`` and ``transact`` on one UART; ``latency_us`` is added to every receive
    timeout (0 on the board; a pty or USB adapter delivers bytes late). A UART with a
    ``wait()`` (block briefly until a byte may be there) is waited on instead of polled in
    a busy loop, which on a shared host would starve the simulator it is talking to."""

    def __init__(self, uart, baud=1000000, direction=None, latency_us=0):
        self.uart = uart
        self.wait = getattr(uart, "wait", None)
        self.dir = direction
        self.char_us = (10 * 1000000) // baud + 1
        self.latency_us = latency_us

    def _send(self, buf, n):
        d = self.dir
        if d is not None:
            d.value(1)
        self.uart.write(memoryview(buf)[:n])
        if d is not None:
            time.sleep_us(self.char_us)  # write returns when the last byte is in the shifter
            d.value(0)

    def write(self, buf, n):
        self._send(buf, n)

    def transact(self, buf, n, rx, nrx, timeout_us):
        """Send ``buf[:n]``; receive up to ``nrx`` bytes into ``rx`` within ``timeout_us``.
        With ``n`` 0 only receive, keeping what the UART holds (the rest of a reply)."""
        uart = self.uart
        if n:
            while uart.any():
                uart.read()  # stale bytes from an earlier, timed-out reply
            self._send(buf, n)
        deadline = time.ticks_add(time.ticks_us(), timeout_us + self.latency_us)
        got = 0
        mv = memoryview(rx)
        while got < nrx and time.ticks_diff(deadline, time.ticks_us()) > 0:
            if uart.any():
                k = uart.readinto(mv[got:nrx])
                got += k if k else 0
            elif self.wait is not None:
                self.wait()
        return got

