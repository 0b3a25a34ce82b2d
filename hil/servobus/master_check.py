"""Master conformance: what the bus master does wrong by the AX-12 rules, counted and timed.

The conformance checker (host_tools/dynamixel/conformance/v1.py) tests servos; this tests masters. The
``Bus`` hands every burst the master sends to ``MasterCheck.master_bytes`` before the line
sees it (so injected bit errors are not blamed on the master), and the check parses the
bytes with their own arrival times. Violation kinds (``KINDS``):

* ``eeprom_busy``: a packet to a device still deaf after an EEPROM write (hil/servobus/ax12_servo.py);
* ``unsupported_instruction``: not one of the AX-12's seven (no BULK_READ, SYNC_READ, REBOOT);
* ``bad_write``: WRITE/REG_WRITE/SYNC_WRITE to a read-only or reserved cell, past the table,
  or a value out of the field's range (the device's own ``check_write``);
* ``inter_byte_gap``: over 100 ms between bytes of one packet (the servo drops it);
* ``broadcast_read_ping``: READ or PING to ID 254 (no servo answers a broadcast);
* ``talk_over_reply``: a new packet before the previous status could have fully arrived;
* ``bad_checksum``: a packet whose checksum is wrong;
* ``tx_while_receiving``, ``rx_while_transmitting``: the virtual board's direction pin was
  low while the master wrote, or high while a status arrived (hil/link/board_line.py).

The rules are the protocol's (hil/servobus/protocols/: ``Packet1Check``, ``Packet2Check``). On
a Protocol 2.0 line (``MasterCheck(protocol=2)``) the same kinds are named by the X-series
rules: ``bad_checksum`` is a bad CRC, ``bad_write`` is any
write the servo refuses (the EEPROM lock included), ``broadcast_read_ping`` a READ to the
broadcast ID (a broadcast PING is fine), and ``group_read_not_broadcast`` a sync or bulk
read not sent to ID 254.
"""
from __future__ import annotations

from typing import Any

from hexhil.hil.servobus import protocols
from hexhil.hil.servobus.packet_check import KINDS, OnViolation

MAX_EVENTS = 1000  # kept with their times for the summary; counts go on past it


class MasterCheck:
    """Fed by ``Bus.monitor``; ``counts``, ``first_us`` and ``events`` for the summary."""

    def __init__(self, on_violation: OnViolation | None = None, protocol: int = 1) -> None:
        rules = protocols.RULES[protocol]
        self.on_violation = on_violation
        self.counts = {k: 0 for k in rules.kinds}
        self.first_us: dict[str, int] = {}
        self.events: list[tuple[int, str, str]] = []
        self.protocol = protocol
        self._check = rules.check(self._flag)

    def _flag(self, t_us: int, kind: str, detail: str) -> None:
        self.counts[kind] += 1
        self.first_us.setdefault(kind, t_us)
        if len(self.events) < MAX_EVENTS:
            self.events.append((t_us, kind, detail))
        if self.on_violation is not None:
            self.on_violation(t_us, kind, detail)

    def direction_mistake(self, t_us: int, kind: str, detail: str) -> None:
        """The virtual board's direction pin was wrong (``tx_while_receiving`` or
        ``rx_while_transmitting``, hil/link/board_line.py)."""
        self._flag(t_us, kind, detail)

    def master_bytes(self, bus: Bus, t0_us: int, data: bytes) -> None:
        """A burst the master starts sending at ``t0_us`` (before the line delivers it)."""
        end_us = bus.reply_end_us()
        if end_us is not None and end_us > t0_us:   # a status still on its way
            self._flag(t0_us, "talk_over_reply", "master sent before the status had arrived")
        self._check.feed(bus, t0_us, data)

    def summary(self) -> dict[str, Any]:
        """Counts per kind, first time of each, and the first few events (JSON-ready)."""
        return {"counts": dict(self.counts), "total": sum(self.counts.values()),
                "first_s": {k: round(t * 1e-6, 6) for k, t in self.first_us.items()},
                "events": [{"t_s": round(t * 1e-6, 6), "kind": k, "detail": d}
                           for t, k, d in self.events[:20]]}
