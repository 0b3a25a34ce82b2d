"""Master conformance: what the bus master does wrong by the AX-12 rules, counted and timed.

The conformance checker (host_tools/conformance.py) tests servos; this tests masters. The
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

On a Protocol 2.0 line (``MasterCheck(protocol=2)``) the same kinds are named by the
X-series rules (hil/servobus/master_check2.py): ``bad_checksum`` is a bad CRC, ``bad_write`` is any
write the servo refuses (the EEPROM lock included), ``broadcast_read_ping`` a READ to the
broadcast ID (a broadcast PING is fine), and ``group_read_not_broadcast`` a sync or bulk
read not sent to ID 254.
"""
from __future__ import annotations

from typing import Any, Callable

from hil.servobus.packet_check import PacketCheck
from protocol.dynamixel import v1 as dxl

KINDS = ("eeprom_busy", "unsupported_instruction", "bad_write", "inter_byte_gap",
         "broadcast_read_ping", "talk_over_reply", "bad_checksum", "tx_while_receiving",
         "rx_while_transmitting")
KINDS_2 = KINDS + ("group_read_not_broadcast",)   # Protocol 2.0
MAX_EVENTS = 1000  # kept with their times for the summary; counts go on past it

OnViolation = Callable[[int, str, str], None]


class MasterCheck:
    """Fed by ``Bus.monitor``; ``counts``, ``first_us`` and ``events`` for the summary."""

    def __init__(self, on_violation: OnViolation | None = None, protocol: int = 1) -> None:
        self.on_violation = on_violation
        self.counts = {k: 0 for k in (KINDS_2 if protocol == 2 else KINDS)}
        self.first_us: dict[str, int] = {}
        self.events: list[tuple[int, str, str]] = []
        self.protocol = protocol
        if protocol == 2:
            from hil.servobus.master_check2 import Packet2Check
            self._check: PacketCheck = Packet2Check(self._flag)
        else:
            self._check = Packet1Check(self._flag)

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

    def master_bytes(self, bus: Any, t0_us: int, data: bytes) -> None:
        """A burst the master starts sending at ``t0_us`` (before the line delivers it)."""
        if bus.reply_arriving_after(t0_us):
            self._flag(t0_us, "talk_over_reply", "master sent before the status had arrived")
        self._check.feed(bus, t0_us, data)

    def summary(self) -> dict[str, Any]:
        """Counts per kind, first time of each, and the first few events (JSON-ready)."""
        return {"counts": dict(self.counts), "total": sum(self.counts.values()),
                "first_s": {k: round(t * 1e-6, 6) for k, t in self.first_us.items()},
                "events": [{"t_s": round(t * 1e-6, 6), "kind": k, "detail": d}
                           for t, k, d in self.events[:20]]}


class Packet1Check(PacketCheck):
    """The AX-12 rules (Protocol 1.0)."""

    def __init__(self, flag: OnViolation) -> None:
        PacketCheck.__init__(self, flag, dxl.Parser())

    def bad(self) -> int:
        return self.parser.bad_checksum

    def bad_detail(self) -> str:
        return f"packet to id {self.parser.last_bad_checksum_id}"

    def packet(self, bus: Any, t_us: int) -> None:
        p = self.parser
        dev_id, code = p.id, p.code
        params = bytes(p.buf[dxl.PARAMS_OFFSET:dxl.PARAMS_OFFSET + p.nparams])
        name = dxl.INSTRUCTION_NAMES.get(code)
        if name is None:
            self.flag(t_us, "unsupported_instruction", f"instruction 0x{code:02X} to id {dev_id}")
            return
        broadcast = dev_id == dxl.BROADCAST_ID
        if broadcast and code in (dxl.READ, dxl.PING):
            self.flag(t_us, "broadcast_read_ping", f"{name} to the broadcast ID")
        targets = bus.servos if broadcast else [d for d in bus.servos if d.id == dev_id]
        busy = [d.id for d in targets if t_us < getattr(d, "busy_until_us", 0)]
        if busy and (not broadcast or code != dxl.SYNC_WRITE or self._sync_ids(params) & set(busy)):
            self.flag(t_us, "eeprom_busy", f"{name} while id {busy[0]} writes its EEPROM")
        for d, address, value in self._writes(code, dev_id, params, targets):
            if d.check_write(address, value) & dxl.ERR_RANGE:
                self.flag(t_us, "bad_write", f"{name} id {d.id} address {address} "
                                             f"data {value.hex()}")

    @staticmethod
    def _sync_ids(params: bytes) -> set[int]:
        if len(params) < 2 or params[1] == 0:
            return set()
        return set(params[2::params[1] + 1])

    @staticmethod
    def _writes(code: int, dev_id: int, params: bytes, targets: list) -> list:
        """(device, address, data) of every write the packet asks for."""
        if code in (dxl.WRITE, dxl.REG_WRITE) and len(params) >= 2:
            return [(d, params[0], bytes(params[1:])) for d in targets]
        if code != dxl.SYNC_WRITE or len(params) < 2 or params[1] == 0:
            return []
        stride = params[1] + 1
        out = []
        for i in range(2, len(params) - stride + 1, stride):
            for d in targets:
                if d.id == params[i]:
                    out.append((d, params[0], bytes(params[i + 1:i + stride])))
        return out
