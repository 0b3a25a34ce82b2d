"""HAL back end for the real robot: STM32F411 (seed 003 Sec. 3.1), MicroPython stm32 port.

The servo line is USART2 at 1 Mbps through the 74HC126/74HC04 direction circuit (one GPIO
selects transmit or receive); the six limit switches are inputs with pull-ups, closed =
pressed (read low). The F411 has no CAN controller: on a port with ``pyb.CAN`` (F405,
F446...) CAN bus 1 at 500 kbit/s is used, otherwise frames are counted and dropped.
Cannot run on the host; it is compiled with mpy-cross to keep it honest.
"""
import time

import machine

try:
    import pyb
except ImportError:
    pyb = None

UART_ID = 2
DIR_PIN = "A1"        # high: transmit (74HC126 enabled), low: receive
SWITCH_PINS = ("B0", "B1", "B2", "B3", "B4", "B5")  # leg order LF, LM, LH, RF, RM, RH
CAN_BAUD = 500000


class HalfDuplexUART:
    def __init__(self, baud=1000000):
        self.uart = machine.UART(UART_ID, baud, bits=8, parity=None, stop=1,
                                 timeout=0, timeout_char=0, rxbuf=512)
        self.dir = machine.Pin(DIR_PIN, machine.Pin.OUT, value=0)
        self.char_us = (10 * 1000000) // baud + 1
        self.mv = None

    def _send(self, buf, n):
        self.dir.value(1)
        self.uart.write(memoryview(buf)[:n])
        time.sleep_us(self.char_us)  # write returns when the last byte is in the shifter
        self.dir.value(0)

    def write(self, buf, n):
        self._send(buf, n)

    def transact(self, buf, n, rx, nrx, timeout_us):
        """Send ``buf[:n]``; receive up to ``nrx`` bytes into ``rx`` within ``timeout_us``."""
        while self.uart.any():
            self.uart.read()  # stale bytes from an earlier, timed-out reply
        self._send(buf, n)
        deadline = time.ticks_add(time.ticks_us(), timeout_us)
        got = 0
        mv = memoryview(rx)
        while got < nrx and time.ticks_diff(deadline, time.ticks_us()) > 0:
            if self.uart.any():
                k = self.uart.readinto(mv[got:nrx])
                got += k if k else 0
        return got


class CANPort:
    def __init__(self):
        self.dropped = 0
        self.can = None
        if pyb is not None and hasattr(pyb, "CAN"):
            self.can = pyb.CAN(1, pyb.CAN.NORMAL, baudrate=CAN_BAUD)
            self.can.setfilter(0, pyb.CAN.MASK16, 0, (0, 0, 0, 0))

    def send(self, data, arb_id):
        if self.can is None:
            self.dropped += 1
            return
        try:
            self.can.send(data, arb_id, timeout=0)
        except OSError:
            self.dropped += 1

    def any(self):
        return self.can is not None and self.can.any(0)

    def recv(self):
        arb_id, _, _, data = self.can.recv(0, timeout=0)[:4]
        return arb_id, data


class _Switch:
    def __init__(self, name):
        self.pin = machine.Pin(name, machine.Pin.IN, machine.Pin.PULL_UP)

    def value(self):
        return 0 if self.pin.value() else 1  # closed switch pulls the input low


class Board:
    def __init__(self, baud=1000000):
        self.uart = HalfDuplexUART(baud)
        self.can = CANPort()
        self.switches = [_Switch(p) for p in SWITCH_PINS]
        self.ended = False

    def config(self):
        return {}

    def ticks_us(self):
        return time.ticks_us()

    def ticks_diff(self, a, b):
        return time.ticks_diff(a, b)

    def ticks_add(self, a, dt):
        return time.ticks_add(a, dt)

    def perf_us(self):
        return time.ticks_us()

    def io_us(self):
        return 0

    def sleep_until(self, t_us):
        dt = time.ticks_diff(t_us, time.ticks_us())
        if dt > 0:
            time.sleep_us(dt)

    def event(self, kind, text):
        print("event", kind, text)

    def close(self):
        pass
