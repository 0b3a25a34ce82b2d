"""The ELF board's side of the world: what a link reply brings (the switch levels and their
EXTI edges, the servo line's reply on its way, CAN frames, the run's end), and when the board
asks the world again while the firmware does not: a sleep to now after a quiet while, each
millisecond while an interrupt waits for a switch or a CAN frame, else every 10 ms; a read
of the switch pins asks for fresh levels itself (``fresh_switches``; board_core.c
``switches_idr`` asks the same in C). Every request is in the trace's ``/link``, which
``hexhil replay`` serves back: when to ask depends on nothing but the board's own time."""
from __future__ import annotations

from typing import Any

from hexhil.hil.mcu.board_core import SharedField
from hexhil.hil.mcu.gpio_registers import SWITCH_PINS
from hexhil.hil.mcu.link_client import Reply
from hexhil.hil.mcu.timebase import FS_PER_US, TICK_US

IDLE_TICKS = 10              # the ticks between sleeps when nothing listens


class WorldSync:
    last_request_us = SharedField("last_request_us")      # the switches are as old as it

    def __init__(self, board: Any) -> None:
        self.board = board
        self.shared = board.core.shared
        self.last_request_us = -TICK_US
        self.tick = board.events.timer(self._tick)
        self.tick.set(TICK_US * FS_PER_US)

    def take(self, reply: Reply) -> Reply:
        board = self.board
        if reply.switches != board.switches:
            port = board.gpio[1]
            before = port.idr()
            board.switches = reply.switches
            after = port.idr()
            for p in range(SWITCH_PINS):
                if (after ^ before) >> p & 1:
                    board.exti.edge(1, p, bool(after >> p & 1))
        board.line.reply(reply.next_rx_us, reply.pending)
        for arb_id, data in reply.can:
            board.can_received(arb_id, data)
        if reply.ended:
            board.ended = True
            board.core.stop()
        self.last_request_us = board.link.t_us
        return reply

    def _tick(self, at_fs: int) -> None:
        board = self.board
        at_us = at_fs // FS_PER_US
        if at_us - self.last_request_us >= TICK_US:
            self.take(board.link.sleep(at_us))
        board.faults.sample()
        board.endings.sample()
        listening = board.exti.regs[0x00] & 0x3F or board.can_listening
        self.tick.set(at_fs + (1 if listening else IDLE_TICKS) * TICK_US * FS_PER_US)

    def fresh_switches(self) -> None:
        """The firmware reads port B: the switch levels of the last millisecond."""
        now_us = self.board.now_us()
        if now_us - self.last_request_us >= TICK_US:
            self.take(self.board.link.sleep(now_us))
