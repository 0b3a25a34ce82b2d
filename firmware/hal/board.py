"""HAL back end for the real robot: STM32F411 (seed 003 Sec. 3.1), MicroPython stm32 port.

The servo line is USART2 at 1 Mbps through the 74HC126/74HC04 direction circuit (one GPIO
selects transmit or receive); the six limit switches are inputs with pull-ups, closed =
pressed (read low). The F411 has no CAN controller: on a port with ``pyb.CAN`` (F405,
F446...) CAN bus 1 at 500 kbit/s is used, otherwise frames are counted and dropped.
The core sleeps (WFI) between cycles, and the servos answer after a return delay that
leaves the interpreter time to turn the line round (docs/micropython-on-the-chip.md).
Runs on MicroPython's stm32 port (and the unix port's virtual board), not under CPython.
"""
import time

import machine

from firmware.hal import base
from firmware.hal.realtime import HalfDuplexUART
from protocol import link_schema as ls

try:
    import pyb
except ImportError:
    pyb = None

UART_ID = 2
DIR_PIN = "A1"        # high: transmit (74HC126 enabled), low: receive
SWITCH_PINS = ("B0", "B1", "B2", "B3", "B4", "B5")  # leg order LF, LM, LH, RF, RM, RH
CAN_BAUD = 500000
# The servos' return delay: a reply that starts before the interpreter lowers the direction
# line is lost. A write costs 67-78 us beyond its wire time on the emulated 100 MHz F411,
# part of it before the first byte; with the factory's 0 us the acknowledgements are lost.
RETURN_DELAY_US = 100


class CANPort(base.CAN):
    """``pyb.CAN`` bus 1 where the chip has one; otherwise the base's count-and-drop."""

    def __init__(self):
        base.CAN.__init__(self)
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
        return arb_id, bytes(data)


class _Switch:
    def __init__(self, name):
        self.pin = machine.Pin(name, machine.Pin.IN, machine.Pin.PULL_UP)

    def value(self):
        return 0 if self.pin.value() else 1  # closed switch pulls the input low


class Board(base.Board):
    """The robot: wall clock, events on the REPL's stdout (base), the return delay it needs."""

    def __init__(self, baud=1000000):
        uart = machine.UART(UART_ID, baud, bits=8, parity=None, stop=1,
                            timeout=0, timeout_char=0, rxbuf=512)
        self.uart = HalfDuplexUART(uart, baud, machine.Pin(DIR_PIN, machine.Pin.OUT, value=0))
        self.can = CANPort()
        self.switches = [_Switch(p) for p in SWITCH_PINS]

    def config(self):
        return {ls.RETURN_DELAY_US: RETURN_DELAY_US}

    def sleep_until(self, t_us):
        """Whole milliseconds in ``sleep_ms`` (WFI until each SysTick: the core sleeps), the
        rest in ``sleep_us`` (a busy wait)."""
        dt = time.ticks_diff(t_us, time.ticks_us())
        if dt > 1000:
            time.sleep_ms(dt // 1000)
        base.Board.sleep_until(self, t_us)
