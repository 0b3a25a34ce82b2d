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
from hexhil.hil.mcu.usart import Usart
from hexhil.hil.servobus.line import resample

LINE_BAUD = 1_000_000
BAUD_TOLERANCE = 0.03        # a UART frame survives about this much clock error


class ServoLine:
    direction = SharedField("direction")     # PA1's level: board_core.c turns it too

    def __init__(self, board: Any) -> None:
        self.board = board
        self.shared = board.core.shared
        self.direction = 0
        self._burst = bytearray()
        self._burst_fs = 0
        self._burst_dir = 0
        self._bad_baud: set[int] = set()
        self.rx_timer = board.events.timer(self.rx_arrives)
        self.deliver_timer = board.events.timer(self.deliver)
        if board.native:          # the compiled heap delivers the bytes (board_core.c)
            board.core.shared.rx_tid = self.deliver_timer.tid
        self._rx_queue: list[tuple[int, int]] = []
        self._rx_burst = (0, 0)        # (first byte's arrival, bytes back to back)

    def reply(self, next_rx_us: int, pending: int) -> None:
        """What the host said is on its way to the master."""
        if next_rx_us and pending:
            self._rx_burst = (next_rx_us, pending)
            self.rx_timer.set(max(next_rx_us * FS_PER_US, self.board.core.now_fs()))
        else:
            self.rx_timer.clear()

    def sent(self, usart: Usart, byte: int, start_fs: int, end_fs: int) -> None:
        if not self._burst:
            self._burst_fs, self._burst_dir = start_fs, self.direction
        self._burst.append(byte)

    def idle(self, usart: Usart, at_fs: int) -> None:
        self.flush()

    def pin(self, level: int) -> None:
        """PA1 drives ``level`` now."""
        if level != self.direction:
            self.direction_turned(level)

    def _gather(self) -> None:
        """The compiled USART2 (hil/mcu/board_core.c) keeps the burst it sends: take it."""
        got = self.board.native.burst() if self.board.native else None
        if got is not None:
            self._burst = bytearray(got[0])
            self._burst_fs, self._burst_dir = got[1], got[2]

    def flush(self) -> None:
        self._gather()
        if not self._burst:
            return
        tx, self._burst = bytes(self._burst), bytearray()
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
        self.board.cycles.burst(self._burst_fs, self.board.rcc.hclk_hz, tx)   # deadline.py
        self.board.sync.take(self.board.link.line(self._burst_fs // FS_PER_US, tx,
                                             bool(self._burst_dir), False, 0))

    def direction_turned(self, level: int) -> None:
        usart = self.board.usart2
        self._gather()
        if self._burst and usart.shift_end.at_fs is not None and not level:
            self._burst.pop()     # the byte on the wire now is cut by the turn
            self.board.link.fault("tx_while_receiving", "1 byte cut: the direction pin (A1) turned "
                            "low while it was on the wire (turn after TC, not TXE)")
        native = self.board.native
        waiting = native.rx_waiting() if native else len(self._rx_queue)
        if level and waiting:
            self.board.link.fault("rx_while_transmitting", f"{waiting} status bytes "
                            "arrived while the direction pin (A1) was high: the receiver was off")
            if native:
                native.clear_rx()
            self._rx_queue.clear()
            self.deliver_timer.clear()
        self.flush()
        self.direction = level
        self.board.link.direction(self.board.now_us(), bool(level))

    def rx_arrives(self, at_fs: int) -> None:
        """The first byte of a burst arrives: fetch the whole burst at once (the host's
        clock runs ahead by its length) and hand each byte to USART2 at its own time."""
        first_us, pending = self._rx_burst
        byte_us = 10_000_000 / int(self.board.link.config.get("baud", LINE_BAUD))
        last_us = first_us + int((pending - 1) * byte_us) + 1
        reply = self.board.link.line(last_us, b"", bool(self.direction), True, pending)
        queue = [(at_fs + round(k * byte_us * FS_PER_US), b) for k, b in enumerate(reply.rx)]
        if self.board.native:
            self.board.native.queue_rx(queue)
        else:
            self._rx_queue = queue
        self.board.sync.take(reply)
        self.deliver(at_fs)

    def deliver(self, at_fs: int) -> None:
        if self.board.native:
            self.board.native.deliver(at_fs)
            return
        queue = self._rx_queue
        while queue and queue[0][0] <= at_fs:
            self.board.usart2.received(queue.pop(0)[1])
        if queue:
            self.deliver_timer.set(queue[0][0])
