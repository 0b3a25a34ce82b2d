"""A master's burst checked byte by byte against one protocol's rules (hil/servobus/protocols/:
v1.py's ``Packet1Check``, v2.py's ``Packet2Check``): the loop and the kinds they share."""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable

if TYPE_CHECKING:
    from hexhil.hil.servobus.line import Bus

# What a master can do wrong on any Dynamixel line (hil/servobus/master_check.py says each);
# a protocol adds its own (hil/servobus/protocols/).
KINDS = ("eeprom_busy", "unsupported_instruction", "bad_write", "inter_byte_gap",
         "broadcast_read_ping", "talk_over_reply", "bad_checksum", "tx_while_receiving",
         "rx_while_transmitting")

OnViolation = Callable[[int, str, str], None]


class PacketCheck:
    """One protocol's rules for a master's packets. ``feed`` parses a burst with its bytes'
    arrival times and flags gaps and failed checks through ``flag``; a subclass counts the
    failed checks (``bad``, ``bad_detail``) and judges each packet the parser completes
    (``packet``)."""

    def __init__(self, flag: OnViolation, parser: Any) -> None:
        self.flag = flag
        self.parser = parser

    def feed(self, bus: "Bus", t0_us: int, data: bytes) -> None:
        p = self.parser
        gaps, bad = p.timeouts, self.bad()
        for i, byte in enumerate(data):
            t = bus.byte_end_us(t0_us, i)
            done = p.push(byte, t)
            if p.timeouts != gaps:
                gaps = p.timeouts
                self.flag(t, "inter_byte_gap", "over 100 ms between bytes; partial packet dropped")
            if self.bad() != bad:
                bad = self.bad()
                self.flag(t, "bad_checksum", self.bad_detail())
            if done:
                self.packet(bus, t)

    def bad(self) -> int:
        raise NotImplementedError

    def bad_detail(self) -> str:
        raise NotImplementedError

    def packet(self, bus: "Bus", t_us: int) -> None:
        raise NotImplementedError
