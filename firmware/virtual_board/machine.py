"""Stand-in for MicroPython's ``machine`` on the virtual STM32F411 board (seed 003 Sec. 3.1).

The wiring (docs/your-firmware.md): ``UART(2)`` is the servo line, ``Pin("A1")`` the
74HC126/74HC04 direction line (high: transmit), ``Pin("B0")``..``Pin("B5")`` the limit
switches LF, LM, LH, RF, RM, RH with pull-ups (pressed reads 0). Other pins keep the level
written to them and drive nothing. Time is vboard.py's virtual time.
"""
import vboard


FREQ_HZ = 100000000   # the STM32F411RE (seed 003 Sec. 3.1) at its rated maximum clock (ST datasheet)


def freq():
    return FREQ_HZ


def idle():
    """Wait for an interrupt: on the board, one busy-wait poll (vboard.py)."""
    vboard.board().poll()


def _switch_index(name):
    return vboard.SWITCH_PINS.index(name) if name in vboard.SWITCH_PINS else -1


class Pin:
    IN = 0
    OUT = 1
    OPEN_DRAIN = 2
    PULL_NONE = None
    PULL_UP = 1
    PULL_DOWN = 2
    IRQ_FALLING = 1
    IRQ_RISING = 2

    _levels = {}    # pin name -> level written (board-wide, as the hardware's)

    def __init__(self, name, mode=-1, pull=-1, value=None):
        self.name = name
        self.board = vboard.board()
        self.switch = _switch_index(name)
        if value is not None:
            self.value(value)

    def value(self, x=None):
        if x is None:
            return self._read()
        level = 1 if x else 0
        Pin._levels[self.name] = level
        if self.name == vboard.DIR_PIN and bool(level) != self.board.dir_tx:
            self.board.turn(level)   # the host turns the line round at this instant
        return None

    def _read(self):
        b = self.board
        b.poll()
        if self.switch >= 0:
            return 0 if b.switch_bits & (1 << self.switch) else 1
        return Pin._levels.get(self.name, 0)

    def __call__(self, x=None):
        return self.value(x)

    def on(self):
        self.value(1)

    def off(self):
        self.value(0)

    def high(self):
        self.value(1)

    def low(self):
        self.value(0)

    def irq(self, handler=None, trigger=3):
        """Call ``handler(pin)`` on the switch's edges (falling: pressed), checked whenever
        the board hears from the host. Only the six switch pins have edges."""
        if self.switch < 0:
            raise ValueError("Pin(%r): only the switch pins B0-B5 have edges" % self.name)
        if handler is None:
            self.board.irqs.pop(self.switch, None)
        else:
            self.board.irqs[self.switch] = (self, handler, trigger)


def _char_timeout_us(timeout_char_ms):
    """The stm32 port keeps ``timeout_char`` at least 13 bit times, rounded up to 1 ms."""
    return max(timeout_char_ms, 13000 // vboard.BAUD + 1) * 1000


class UART:
    """USART2 on the half-duplex servo line. ``write`` returns when the last byte is in
    the shift register; ``flush`` waits until it has left the wire; ``timeout`` (first
    byte) and ``timeout_char`` (between bytes) are milliseconds of virtual time."""

    def __init__(self, uart_id, baudrate=vboard.BAUD, bits=8, parity=None, stop=1,
                 timeout=0, timeout_char=0, rxbuf=64, **kw):
        if uart_id != vboard.UART_ID:
            raise ValueError("UART(%s) is not wired: the servo line is UART(2)" % uart_id)
        if baudrate != vboard.BAUD:
            raise ValueError("the servo line runs at %d baud, not %s" % (vboard.BAUD, baudrate))
        self.board = vboard.board()
        self.timeout_us = timeout * 1000
        self.timeout_char_us = _char_timeout_us(timeout_char)

    def init(self, baudrate=vboard.BAUD, bits=8, parity=None, stop=1, timeout=None,
             timeout_char=None, **kw):
        if timeout is not None:
            self.timeout_us = timeout * 1000
        if timeout_char is not None:
            self.timeout_char_us = _char_timeout_us(timeout_char)

    def write(self, buf):
        b = self.board
        b.flush_tx()
        b.line(bytes(buf))
        return len(buf)

    def any(self):
        b = self.board
        b.poll()
        return b.rx_count()

    def txdone(self):
        b = self.board
        b.poll()
        return b.now_us >= b.tx_end_us

    def flush(self):
        self.board.flush_tx()

    def _collect(self, n):
        """Up to ``n`` bytes (None: until a gap), waiting ``timeout`` for the first and
        ``timeout_char`` between the next."""
        b = self.board
        out = bytearray()
        wait = self.timeout_us
        while n is None or len(out) < n:
            if not b.rxbuf and not b.wait_rx(0 if n is None else n - len(out), b.now_us + wait):
                break
            k = len(b.rxbuf) if n is None else min(n - len(out), len(b.rxbuf))
            out.extend(b.rxbuf[:k])
            b.rxbuf = b.rxbuf[k:]
            wait = self.timeout_char_us
        return out

    def read(self, nbytes=None):
        out = self._collect(nbytes)
        return bytes(out) if out else None

    def readinto(self, buf, nbytes=None):
        n = len(buf) if nbytes is None else min(nbytes, len(buf))
        out = self._collect(n)
        buf[:len(out)] = out
        return len(out) if out else None

    def readline(self):
        b = self.board
        out = bytearray()
        wait = self.timeout_us
        while True:
            if not b.rxbuf and not b.wait_rx(1, b.now_us + wait):
                break
            c = b.rxbuf[0]
            b.rxbuf = b.rxbuf[1:]
            out.append(c)
            if c == 0x0A:
                break
            wait = self.timeout_char_us
        return bytes(out) if out else None

    def deinit(self):
        pass
