"""The host side of the virtual STM32F411 board (firmware/virtual_board/).

``BoardLine`` answers the link's line request (docs/link.md "L line"): the board's UART
behind its 74HC126/74HC04 direction circuit, in virtual time. Bytes written while the
direction pin is low do not reach the line; bytes that arrive while it is high are lost.
Both are the master's mistakes: counted in the run's faults, recorded, and handed to the
master check (hil/servobus/master_check.py) when one watches the bus.

The firmware itself is started and judged by hil/link/served_firmware.py ``BoardFirmware``.
"""
from __future__ import annotations

import struct
from typing import Mapping

from hexhil.hil.link.firmware_process import LinkViolation
from hexhil.hil.run_result import RunTally
from hexhil.hil.seams import LinkHost, ServoLine
from hexhil.protocol import sim_link

HANG_S = 2.0          # virtual seconds without a UART write, pin turn or sleep: a hang
TX_WHILE_RECEIVING = "tx_while_receiving"
RX_WHILE_TRANSMITTING = "rx_while_transmitting"
MISTAKES = (TX_WHILE_RECEIVING, RX_WHILE_TRANSMITTING)
WRONG_BAUD = "wrong_baud"


def set_master_baud(server: LinkHost, payload: bytes, result: RunTally) -> None:
    """A posted baud message (the C SDK's ``HAL_UART_Init`` of USART2): the master's UART
    runs at that rate from now on. The servos decode it with their own timing
    (hil/servobus/wire.py ``resample``), so at a rate they do not listen at they hear garbage and do
    not answer, as on the robot (the virtual board's ``machine.UART`` refuses such a rate
    outright); the run counts a ``wrong_baud`` fault that says so."""
    if len(payload) != sim_link.BAUD_LEN:
        raise LinkViolation(f"malformed baud message ({len(payload)} bytes, not 4)")
    (bps,) = struct.unpack_from("<I", payload, 0)
    if bps == 0:
        raise LinkViolation("a baud message of 0 bit/s")
    bus = server.bus
    listening = sorted({s.baud_bps for s in bus.servos})
    bus.set_master_baud(bps)
    server.byte_us = 10_000_000 / bps
    if bps not in listening:
        server.run_fault(WRONG_BAUD, f"the servo UART (USART2) runs at {bps} baud; the servos "
                         f"listen at {', '.join(map(str, listening))} baud", result)


def why_no_servo_answered(bus: ServoLine | None, faults: Mapping[str, int]) -> str | None:
    """One line when the master wrote on the line and no servo ever answered: which of
    its mistakes the run saw (direction pin low, a rate the servos do not listen at,
    IDs no servo has); None when some servo answered or nothing was written."""
    if bus is None or bus.stats["replies"] or not (bus.stats["tx_bytes"]
                                                   or faults.get(TX_WHILE_RECEIVING)):
        return None
    causes = []
    if faults.get(TX_WHILE_RECEIVING):
        causes.append(f"{faults[TX_WHILE_RECEIVING]} writes went out while the direction "
                      f"pin (A1) was low ({TX_WHILE_RECEIVING})")
    listening = sorted({s.baud_bps for s in bus.servos})
    if bus.baud not in listening:
        causes.append(f"the master's UART ran at {bus.baud} baud, the servos at "
                      f"{', '.join(map(str, listening))} baud")
    missing = sorted(bus.missing_ids)
    if missing and not causes:
        ids = sorted({s.id for s in bus.servos})
        have = f"{ids[0]}-{ids[-1]}" if ids == list(range(ids[0], ids[-1] + 1)) else \
            ", ".join(map(str, ids))
        causes.append(f"the packets went to IDs {', '.join(map(str, missing[:8]))}"
                      f"{' ...' if len(missing) > 8 else ''}, and no servo on the line has "
                      f"them (IDs {have})")
    if not causes:
        causes.append("no valid packet reached them")
    return "no servo answered: " + "; ".join(causes)


class BoardLine:
    """The board's UART and direction line, served for one link (``server``: the
    hil/link/server.py ``LinkServer`` whose bus, clock, switches and hooks it uses)."""

    def __init__(self, server: LinkHost) -> None:
        self.server = server
        self.bus, self.clock = server.bus, server.clock
        self.tx_on = False
        self.quiet_since_us = self.clock.t_us
        self._kept = b""     # bytes received before a turn to transmit, for the next reply

    def active(self) -> None:
        """The firmware did something (a write, a pin turn, a sleep): it is not hung."""
        self.quiet_since_us = self.clock.t_us

    def _lose(self, result: RunTally) -> None:
        lost = self.bus.master_discard()
        if lost:
            self.server.run_fault(RX_WHILE_TRANSMITTING, f"{lost} status bytes arrived while "
                                  "the direction pin (A1) was high: the receiver was off", result)

    def _idle_to(self, t_us: int) -> None:
        if t_us > self.clock.t_us:
            self.server.idle_to(t_us)
            self.server.on_slept()

    def _set_direction(self, tx_on: bool, result: RunTally) -> None:
        """The pin turns now: a turn to receive loses what came in while transmitting;
        a turn to transmit keeps what came in before it."""
        if self.tx_on and not tx_on:
            self._lose(result)
        elif tx_on and not self.tx_on:
            self._kept += self.bus.master_read(sim_link.MAX_RX_LEN, 0)
        self.tx_on = tx_on

    def turn(self, payload: bytes, end_us: int, result: RunTally) -> None:
        """A posted direction message: the pin took ``level`` at ``turn_us``."""
        if len(payload) != sim_link.DIRECTION_LEN:
            raise LinkViolation(f"malformed direction message ({len(payload)} bytes)")
        turn_us, level = struct.unpack_from("<QB", payload, 0)
        self._idle_to(min(turn_us, end_us))
        self.active()
        self._set_direction(bool(level), result)

    def answer(self, payload: bytes, end_us: int, result: RunTally) -> bytes:
        """Carry out one line request; the reply's body (after ``t_us``)."""
        if len(payload) < sim_link.LINE_HEAD_LEN:
            raise LinkViolation(f"malformed line request ({len(payload)} bytes)")
        at_us, flags, nrx = struct.unpack_from("<QBH", payload, 0)
        if nrx > sim_link.MAX_REPLY_LEN - sim_link.LINE_REPLY_HEAD_LEN:
            raise LinkViolation(f"a line request asks for {nrx} bytes, more than a reply holds")
        tx = payload[sim_link.LINE_HEAD_LEN:]
        ended = at_us >= end_us
        clock, bus, server = self.clock, self.bus, self.server
        if ended:
            at_us = end_us
        self._idle_to(at_us)
        tx_on = bool(flags & sim_link.LINE_DIR_TX)
        if not flags & sim_link.LINE_POLL or tx_on != self.tx_on:
            self.active()
        elif clock.t_us - self.quiet_since_us >= HANG_S * 1e6:
            raise LinkViolation(f"the firmware hung: no UART write, direction turn or sleep "
                                f"for {HANG_S:g} virtual seconds (since t={self.quiet_since_us * 1e-6:.6f} s)")
        self._set_direction(tx_on, result)
        if tx_on:
            self._lose(result)   # what came in while transmitting
        if tx and tx_on:
            bus.master_write(tx)
        elif tx:
            self.server.run_fault(TX_WHILE_RECEIVING, f"{len(tx)} bytes written while the "
                                  "direction pin (A1) was low: they did not reach the line",
                                  result)
            bus.idle_until(clock.t_us + bus.wire_us(len(tx)))
        if tx_on:
            self._lose(result)
        rx, self._kept = self._kept[:nrx], self._kept[nrx:]
        if not tx_on and len(rx) < nrx:
            rx += bus.master_read(nrx - len(rx), 0)
        bits = server.switches.sample(clock.t_us, result)
        next_us, pending = bus.next_bytes()
        head = struct.pack("<BBQH", sim_link.FLAG_END if ended else 0, bits,
                           next_us or sim_link.NO_RX, pending)
        return head + rx
