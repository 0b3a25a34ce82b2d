"""The firmware under this CPython, in the host's own process: the runtime of sweeps.

``firmware/main.py`` runs unchanged on the simulator HAL (``firmware/hal/sim.py``), whose
link writes to ``Wire`` instead of a socket. A link call hands the written frames to the
simulator (hil/link.py ``DirectConnection``) and reads its reply back, so a run trades two
process wake-ups a round trip for one function call. Same frames, same answers: the
serial digest is micropython's (tests/test_in_process.py). micropython stays the
reference and the default of ``hexhil run``; this lives on the top floor because it joins
firmware/ and hil/, which never import each other.
"""
from __future__ import annotations

from typing import Callable

from firmware import main as firmware_main
from firmware.hal.sim import Board


class Wire:
    """File-like end of the link for the firmware's ``Link(io=...)``: writes collect until
    the firmware reads, which is when it waits for a reply."""

    def __init__(self, exchange: Callable[[bytes, bool], bytes]) -> None:
        self.exchange = exchange
        self.pending = bytearray()
        self.reply = b""
        self.pos = 0

    def write(self, data: memoryview) -> int:
        self.pending += data
        return len(data)

    def readinto(self, buf: memoryview) -> int:
        if self.pos >= len(self.reply):
            self.reply, self.pos = self.exchange(bytes(self.pending), False), 0
            self.pending.clear()
        n = min(len(buf), len(self.reply) - self.pos)
        buf[:n] = self.reply[self.pos:self.pos + n]
        self.pos += n
        return n

    def close(self) -> None:
        self.exchange(bytes(self.pending), True)
        self.pending.clear()


def run_firmware(exchange: Callable[[bytes, bool], bytes]) -> None:
    """Boot and run the firmware until the simulator ends the run (``Simulator.run``'s
    ``in_process``)."""
    firmware_main.main(Board(io=Wire(exchange)))
