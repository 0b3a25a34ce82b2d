"""The ELF board's side of the world: what a link reply brings (the switch levels and their
EXTI edges, the servo line's reply on its way, CAN frames, the run's end), and when the board
asks the world again while the firmware does not: a sleep to now after a quiet while, each
millisecond while an interrupt waits for a CAN frame, else every 10 ms. A switch interrupt
asks only once the host's word that the levels hold has run out (hil/link/server.py
``SwitchSampler.steady_until``: the world's next physics step), and a read of the switch
pins asks for fresh levels itself (``fresh_switches``; board_core.c ``switches_idr`` asks
the same in C)."""
from __future__ import annotations

from typing import Any, Callable

from hil.mcu.board_core import SharedField
from hil.mcu.core import FS_PER_US
from hil.mcu.gpio import SWITCH_PINS
from hil.mcu.link_client import Reply

TICK_US = 1000               # a quiet millisecond: a sleep to now (world, switches, CAN)
IDLE_TICKS = 10              # the ticks between sleeps when nothing listens


class WorldSync:
    last_request_us = SharedField("last_request_us")      # the switches are as old as it
    switches_until_us = SharedField("switches_until_us")  # ... and stay so until then

    def __init__(self, board: Any, switches_until: Callable[[], int]) -> None:
        self.board = board
        self.shared = board.core.shared
        self.switches_until = switches_until
        self.last_request_us = -TICK_US
        self.switches_until_us = 0
        self.tick = board.events.timer(self._tick)
        self.tick.set(TICK_US * FS_PER_US)

    def take(self, reply: Reply) -> Reply:
        board = self.board
        if reply.switches != board.switches:
            port = board.gpio[1]
            before = [port.input_level(p) for p in range(SWITCH_PINS)]
            board.switches = reply.switches
            for p in range(SWITCH_PINS):
                now = port.input_level(p)
                if now != before[p]:
                    board.exti.edge(1, p, bool(now))
        board.line.reply(reply.next_rx_us, reply.pending)
        for arb_id, data in reply.can:
            board.can_received(arb_id, data)
        if reply.ended:
            board.ended = True
            board.core.stop()
        self.last_request_us = board.link.t_us
        self.switches_until_us = self.switches_until()
        return reply

    def _tick(self, at_fs: int) -> None:
        board = self.board
        at_us = at_fs // FS_PER_US
        exti = board.exti.regs[0x00] & 0x3F
        if board.can_listening or not exti:
            if at_us - self.last_request_us >= TICK_US:
                self.take(board.link.sleep(at_us))
        elif self._switches_stale(at_us):
            self.take(board.link.sleep(at_us))
        board.endings.sample()
        listening = exti or board.can_listening
        self.tick.set(at_fs + (1 if listening else IDLE_TICKS) * TICK_US * FS_PER_US)

    def _switches_stale(self, now_us: int) -> bool:
        """The levels of the last request may have changed by ``now_us``: a millisecond
        old and past the host's word, or as old as the sleeps when nothing listens."""
        quiet_us = now_us - self.last_request_us
        return quiet_us >= TICK_US and (now_us >= self.switches_until_us or
                                        quiet_us >= IDLE_TICKS * TICK_US)

    def fresh_switches(self) -> None:
        """The firmware reads port B: the switch levels as the world has them now."""
        now_us = self.board.now_us()
        if self._switches_stale(now_us):
            self.take(self.board.link.sleep(now_us))
