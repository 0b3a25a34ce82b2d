"""USART2 on the servo line, through the 74HC126/74HC04 direction buffer (PA1), as link
messages (hil/mcu/link_client.py).

A byte burst (bytes back to back) is one line request stamped with its first byte's
start, sent when the last has gone or when PA1 turns; PA1 low while a byte is on the wire
cuts it (``tx_while_receiving``). A baud more than 3 % off the line's is named once
(``uart_baud``) and the servos hear the bytes resampled at their own baud: garbage, no
reply. A reply burst is fetched at its first byte's arrival (the host's clock runs ahead
by its length) and handed to USART2 byte by byte at each byte's own time; PA1 high while
bytes are still arriving loses them (``rx_while_transmitting``).
"""
from __future__ import annotations

from typing import Any

from hexhil.hil.mcu.board_core import SharedField
from hexhil.hil.mcu.timebase import FS_PER_US
from hexhil.hil.servobus.line import resample

LINE_BAUD = 1_000_000
BAUD_TOLERANCE = 0.03        # a UART frame survives about this much clock error


class ServoLine:
    direction = SharedField("direction")     # PA1's level: board_core.c turns it too

    def __init__(self, board: Any) -> None:
        self.board = board
        self.shared = board.core.shared
        self.direction = 0
        self._bad_baud: set[int] = set()
        self.rx_timer = board.events.timer(self.rx_arrives)
        # the C heap hands the reply bytes to USART2 at their times (board_core.c)
        self.deliver_timer = board.events.timer(lambda at_fs: None)
        self.shared.rx_tid = self.deliver_timer.tid
        self._rx_burst = (0, 0)        # (first byte's arrival, bytes back to back)

    def reply(self, next_rx_us: int, pending: int) -> None:
        """What the host said is on its way to the master."""
        if next_rx_us and pending:
            self._rx_burst = (next_rx_us, pending)
            self.rx_timer.set(max(next_rx_us * FS_PER_US, self.board.core.now_fs()))
        else:
            self.rx_timer.clear()

    def pin(self, level: int) -> None:
        """PA1 drives ``level`` now."""
        if level != self.direction:
            self.direction_turned(level)

    def flush(self) -> None:
        """The bytes USART2 sent since the last burst (board_core.c keeps them), as one
        line request."""
        got = self.board.native.burst()
        if got is not None:
            self._send(*got)

    def _send(self, tx: bytes, start_fs: int, direction: int) -> None:
        line = int(self.board.link.config.get("baud", LINE_BAUD))
        baud = round(self.board.usart2.baud())
        if abs(baud - line) > BAUD_TOLERANCE * line:
            if baud not in self._bad_baud:
                self._bad_baud.add(baud)
                usart = self.board.usart2
                self.board.link.fault("uart_baud", f"USART2 runs at {baud} baud (BRR "
                                      f"0x{usart.regs[8]:x}, PCLK1 {self.board.rcc.pclk1_hz} Hz), "
                                      f"the servo line at {line}: the servos hear garbage and "
                                      "never answer")
            tx = resample(tx, max(1, baud), line)
        self.board.cycles.burst(start_fs, self.board.rcc.hclk_hz, tx)   # deadline.py
        self.board.sync.take(self.board.link.line(start_fs // FS_PER_US, tx,
                                                  bool(direction), False, 0))

    def direction_turned(self, level: int) -> None:
        native = self.board.native
        got = native.burst()
        if got is not None and self.board.usart2.shift_end.at_fs is not None and not level:
            got = (got[0][:-1], *got[1:])    # the byte on the wire now is cut by the turn
            self.board.link.fault("tx_while_receiving", "1 byte cut: the direction pin (A1) turned "
                            "low while it was on the wire (turn after TC, not TXE)")
        waiting = native.rx_waiting()
        if level and waiting:
            self.board.link.fault("rx_while_transmitting", f"{waiting} status bytes "
                            "arrived while the direction pin (A1) was high: the receiver was off")
            native.clear_rx()
            self.deliver_timer.clear()
        if got is not None and got[0]:
            self._send(*got)
        self.direction = level
        self.board.link.direction(self.board.now_us(), bool(level))

    def rx_arrives(self, at_fs: int) -> None:
        """The first byte of a burst arrives: fetch the whole burst at once (the host's
        clock runs ahead by its length) and hand each byte to USART2 at its own time."""
        first_us, pending = self._rx_burst
        byte_us = 10_000_000 / int(self.board.link.config.get("baud", LINE_BAUD))
        last_us = first_us + int((pending - 1) * byte_us) + 1
        reply = self.board.link.line(last_us, b"", bool(self.direction), True, pending)
        native = self.board.native
        native.queue_rx([(at_fs + round(k * byte_us * FS_PER_US), b)
                         for k, b in enumerate(reply.rx)])
        self.board.sync.take(reply)
        native.deliver(at_fs)
