"""The virtual STM32F411 board's core: one virtual clock and the simulator link behind the
stand-in ``machine``, ``time`` and ``pyb`` modules of this folder (docs/your-firmware.md).

``hexhil run SCENARIO --firmware MAIN.py`` starts ``micropython MAIN.py`` with this folder
first on ``MICROPYPATH``, so ``import machine`` and ``import time`` find the stand-ins; they
talk to the host over link version 1 (docs/link.md) with firmware/hal/sim.py's ``Link``.

The busy-wait rule: the board keeps its own virtual time ``now_us``. Every call that
reads the board's state (``time.ticks_*``, ``UART.any``/``txdone``, ``Pin.value()`` as a
read) costs ``QUANTUM_US`` of virtual time, as on an instruction-counting emulator, so a
loop that spins on them moves forward, deterministically. Sleeps jump to their end. The
host is asked only when the answer can have changed: a UART write, a read that needs
bytes (each reply says when the next bytes arrive, so ``any()`` counts them without
asking), a sleep of ``SYNC_US`` or more, and after ``SYNC_US`` of local time (switch
levels, the run's end), and a ``print`` while the board is ahead of the host (the host
stamps a printed line with its own time). A turn of the direction pin is posted with the
next question.
CAN frames come with the sleeps, and ``pyb.CAN.any()`` asks for them at most every
``SYNC_US``.
MicroPython-compatible (unix port).
"""
import builtins
import struct

from protocol import sim_link

QUANTUM_US = 5      # virtual time one busy-wait poll costs (a MicroPython call on a 100 MHz M4)
SYNC_US = 1000      # the most local time between two questions to the host
TICKS_PERIOD = 1 << 30   # MicroPython's ticks wrap here (stm32 port)
UART_ID = 2
BAUD = 1000000
DIR_PIN = "A1"
SWITCH_PINS = ("B0", "B1", "B2", "B3", "B4", "B5")  # leg order LF, LM, LH, RF, RM, RH

_board = None
_print = builtins.print


def _link_class():
    """firmware/hal/sim.py's ``Link``, imported with the real ``time`` in place, so that
    its wall-clock profiling (``io_us``) neither costs nor moves virtual time; the HAL's
    base (hal/base.py) is imported first, with this board's ``time``."""
    import sys
    import utime
    import firmware.hal.base  # noqa: F401  (keeps the stand-in time)

    own = sys.modules["time"]
    sys.modules["time"] = utime
    try:
        from firmware.hal.sim import Link
    finally:
        sys.modules["time"] = own
    return Link


def board():
    """The one board of this process, connected at first use."""
    global _board
    if _board is None:
        _board = Board()
    return _board


def _synced_print(*args, **kwargs):
    """``print`` once the host's clock is the board's: the host stamps a printed line with
    its time at the board's next request, so a board ahead of it (busy-wait polls, a sleep
    kept on the board) asks at ``now_us`` first, as a poll does; not from a pin's irq handler,
    which runs while the board takes a reply (its line has the reply's time)."""
    b = _board
    if b is not None and not b.ended and not b.in_handler and b.now_us > b.link.t_us:
        b.line(b"", True)
    _print(*args, **kwargs)


class Board:
    """Virtual time, the UART's receive buffer, the direction level and the switches."""

    def __init__(self):
        import os

        Link = _link_class()
        self.link = Link(int(os.getenv(sim_link.ENV_PORT)))
        hello = bytes((sim_link.VERSION,)) + b"micropython-board"
        self.link.post(sim_link.OP_HELLO, hello, len(hello))
        length = self.link.call()
        rx = self.link.rx
        if length < 10 or rx[8] != sim_link.VERSION:
            raise sim_link.LinkError("link version mismatch: the host speaks version %d, "
                                     "this board speaks %d" % (rx[8] if length > 8 else 0,
                                                              sim_link.VERSION))
        self.now_us = self.link.t_us
        self.switch_bits = rx[9]
        self.dir_tx = False
        self.rxbuf = bytearray()
        self.next_rx_us = 0         # 0: no byte on its way
        self.pending = 0            # bytes arriving back to back from next_rx_us on
        self.tx_end_us = 0          # when the last written byte has left the wire
        self.char_us = 10000000 // BAUD
        self.irqs = {}              # switch index -> (pin, handler, trigger)
        self.can_rx = []
        self.can_sync_us = 0        # when the host last handed CAN frames over
        self.ended = False
        self.in_handler = False     # a pin's irq handler runs (from a reply's switch levels)
        builtins.print = _synced_print

    # --- time -----------------------------------------------------------------------
    def poll(self):
        """One busy-wait poll: the quantum, and the host when an answer may have changed."""
        self.now_us += QUANTUM_US
        if self.ended:   # the run is over; what the firmware does on its way out is free
            return
        if self.now_us - self.link.t_us >= SYNC_US:
            self.line(b"", True)

    def rx_count(self):
        """Bytes received by ``now_us``: the buffer's and those of the announced burst that
        have arrived since (none while the direction pin is high: the receiver is off)."""
        n = len(self.rxbuf)
        if self.next_rx_us and not self.dir_tx and self.now_us >= self.next_rx_us:
            n += min(self.pending, 1 + (self.now_us - self.next_rx_us) // self.char_us)
        return n

    def sleep_until(self, t_us):
        """Idle to ``t_us``: the host moves the world, samples switches, hands CAN frames.
        A sleep that ends within ``SYNC_US`` of the host's time stays on the board; with a
        pin ``irq`` set, the host is asked every ``SYNC_US`` of it."""
        self._check_end()
        if t_us < self.now_us:
            t_us = self.now_us
        if t_us - self.link.t_us < SYNC_US:
            self.now_us = t_us
            return
        while self.irqs and t_us - self.now_us > SYNC_US:   # an edge interrupts the sleep
            self.sync(self.now_us + SYNC_US)
        self.sync(t_us)

    def sync(self, t_us):
        """The host's sleep request to ``t_us``: switches, CAN frames, the run's end."""
        self._check_end()
        link = self.link
        k = link.begin(sim_link.OP_SLEEP, 8)
        struct.pack_into("<Q", link.out, k, t_us)
        flags = self._sleep_reply(link.call())
        while flags & sim_link.FLAG_MORE:
            link.begin(sim_link.OP_MORE, 0)
            flags = self._sleep_reply(link.call())
        self.now_us = max(self.now_us, link.t_us)
        self.can_sync_us = self.now_us
        if flags & sim_link.FLAG_END:
            self._end()

    def can_any(self):
        """Whether a CAN frame waits; with none, the host is asked (a sleep to now) once
        ``SYNC_US`` has passed since it last handed frames over."""
        self.poll()
        if not self.can_rx and self.now_us - self.can_sync_us >= SYNC_US:
            self.sync(self.now_us)
        return len(self.can_rx) > 0

    def _sleep_reply(self, length):
        rx = self.link.rx
        self.now_us = max(self.now_us, self.link.t_us)
        self._switches(rx[9])
        p = sim_link.SLEEP_HEAD_LEN
        for _ in range(rx[10]):
            arb_id, dlc = struct.unpack_from("<HB", rx, p)
            self.can_rx.append((arb_id, bytes(rx[p + 3:p + 3 + dlc])))
            p += sim_link.CAN_RECORD_LEN
        return rx[8]

    # --- the line -------------------------------------------------------------------
    def line(self, tx, poll=False):
        """Ask the host at ``now_us``: write ``tx`` (if any) behind the direction pin, and
        take the bytes that have arrived."""
        self._check_end()
        link = self.link
        n = len(tx)
        k = link.begin(sim_link.OP_LINE, sim_link.LINE_HEAD_LEN + n)
        flags = (sim_link.LINE_DIR_TX if self.dir_tx else 0) | (sim_link.LINE_POLL if poll else 0)
        struct.pack_into("<QBH", link.out, k, self.now_us, flags,
                         sim_link.MAX_RX_LEN - sim_link.LINE_REPLY_HEAD_LEN)
        if n:
            link.out[k + sim_link.LINE_HEAD_LEN:k + sim_link.LINE_HEAD_LEN + n] = tx
        length = link.call()
        rx = link.rx
        self.next_rx_us, self.pending = struct.unpack_from("<QH", rx, 10)
        if length > sim_link.LINE_REPLY_HEAD_LEN:
            self.rxbuf.extend(link.rxmv[sim_link.LINE_REPLY_HEAD_LEN:length])
        if n:   # write returns when the last byte is in the shift register (stm32 port)
            self.tx_end_us = link.t_us
            self.now_us = max(self.now_us, link.t_us - self.char_us)
        else:
            self.now_us = max(self.now_us, link.t_us)
        self._switches(rx[9])
        if rx[8] & sim_link.FLAG_END:
            self._end()

    def turn(self, level):
        """The direction pin turns now: posted to the host (it goes with the next request),
        unless bytes of the announced burst have arrived by now: a turn to transmit
        fetches them first, a turn to receive asks at once (some were lost)."""
        self._check_end()
        due = self.next_rx_us and self.next_rx_us <= self.now_us
        if level and due:
            self.line(b"")
        self.dir_tx = bool(level)
        link = self.link
        k = link.begin(sim_link.OP_DIRECTION, sim_link.DIRECTION_LEN)
        struct.pack_into("<QB", link.out, k, self.now_us, 1 if level else 0)
        if not level and due:
            self.line(b"")

    def flush_tx(self):
        """Wait until the last written byte has left the wire (``UART.flush``)."""
        if self.now_us < self.tx_end_us:
            self.now_us = self.tx_end_us

    def wait_rx(self, want, deadline_us):
        """Move to the arrival of ``want`` more bytes (as many as the announced burst
        holds; 0: all of it), or to ``deadline_us`` if none comes before; fetch what has
        arrived. True if a byte is in the buffer."""
        first = self.next_rx_us
        if first and not self.dir_tx and first <= max(deadline_us, self.now_us):
            k = self.pending if want <= 0 else min(want, self.pending)
            self.now_us = max(self.now_us, first + (k - 1) * self.char_us)
        else:
            self.now_us = max(self.now_us, deadline_us)
        self.line(b"", True)
        return len(self.rxbuf) > 0

    # --- switches -------------------------------------------------------------------
    def _switches(self, bits):
        changed = bits ^ self.switch_bits
        self.switch_bits = bits
        if not changed or not self.irqs:
            return
        for i in range(6):
            if changed & (1 << i) and i in self.irqs:
                pin, handler, trigger = self.irqs[i]
                falling = bits & (1 << i)       # pressed pulls the input low
                if trigger & (pin.IRQ_FALLING if falling else pin.IRQ_RISING):
                    self.in_handler = True    # inside a reply: no question to the host
                    try:
                        handler(pin)
                    finally:
                        self.in_handler = False

    # --- the end ----------------------------------------------------------------------
    def _end(self):
        """The run is over: close the link and leave the firmware (SystemExit, exit 0)."""
        self.ended = True
        self.link.close()
        raise SystemExit(0)

    def _check_end(self):
        if self.ended:
            raise SystemExit(0)

    def post_can(self, arb_id, data):
        n = len(data)
        k = self.link.begin(sim_link.OP_CAN, 3 + n)
        struct.pack_into("<HB", self.link.out, k, arb_id, n)
        self.link.out[k + 3:k + 3 + n] = data

