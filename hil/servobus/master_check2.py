"""The Protocol 2.0 half of the master check (hil/servobus/master_check.py): an X-series master's
mistakes, named with the same kinds (see there)."""
from __future__ import annotations

from typing import Any, Callable

from hil.servobus.packet_check import PacketCheck
from protocol.dynamixel import v2 as dx2

GROUP_READS = (dx2.SYNC_READ, dx2.FAST_SYNC_READ, dx2.BULK_READ, dx2.FAST_BULK_READ)


class Packet2Check(PacketCheck):
    """The X-series rules (Protocol 2.0)."""

    def __init__(self, flag: Callable[[int, str, str], None]) -> None:
        PacketCheck.__init__(self, flag, dx2.Parser())

    def bad(self) -> int:
        return self.parser.bad_crc

    def bad_detail(self) -> str:
        return f"bad CRC in a packet to id {self.parser.last_bad_crc_id}"

    def packet(self, bus: Any, t_us: int) -> None:
        p = self.parser
        dev_id, instr = p.id, p.instr
        params = bytes(p.buf[dx2.PARAMS_OFFSET:dx2.PARAMS_OFFSET + p.nparams])
        name = dx2.INSTRUCTION_NAMES.get(instr)
        if name is None or instr == dx2.STATUS:
            self.flag(t_us, "unsupported_instruction", f"instruction 0x{instr:02X} to id {dev_id}")
            return
        broadcast = dev_id == dx2.BROADCAST_ID
        if broadcast and instr == dx2.READ:
            self.flag(t_us, "broadcast_read_ping", "READ to the broadcast ID (never answered)")
        if instr in GROUP_READS and not broadcast:
            self.flag(t_us, "group_read_not_broadcast", f"{name} to id {dev_id}, not 254")
        targets = bus.servos if broadcast else [d for d in bus.servos if d.id == dev_id]
        busy = [d.id for d in targets if t_us < getattr(d, "busy_until_us", 0)]
        if busy and (not broadcast or instr not in (dx2.SYNC_WRITE, dx2.BULK_WRITE)
                     or set(d for d, _, _ in self._writes(instr, params)) & set(busy)):
            self.flag(t_us, "eeprom_busy", f"{name} while id {busy[0]} writes its EEPROM")
        if instr in (dx2.WRITE, dx2.REG_WRITE) and len(params) >= 3:
            writes = [(d.id, params[0] | params[1] << 8, bytes(params[2:])) for d in targets]
        else:
            writes = self._writes(instr, params)
        for dev, address, value in writes:
            for d in bus.servos:
                if d.id == dev and d.check_write(address, value):
                    error = dx2.error_names(d.check_write(address, value))[0]
                    self.flag(t_us, "bad_write", f"{name} id {dev} address {address} data "
                                                 f"{value.hex()}: {error} error")

    @staticmethod
    def _writes(instr: int, params: bytes) -> list[tuple[int, int, bytes]]:
        """(id, address, data) of each servo's part of a SYNC_WRITE or BULK_WRITE."""
        out = []
        if instr == dx2.SYNC_WRITE and len(params) >= 4:
            a, n = params[0] | params[1] << 8, params[2] | params[3] << 8
            for i in range(4, len(params) - n, n + 1) if n else ():
                out.append((params[i], a, bytes(params[i + 1:i + 1 + n])))
        elif instr == dx2.BULK_WRITE:
            i = 0
            while i + 5 <= len(params):
                n = params[i + 3] | params[i + 4] << 8
                out.append((params[i], params[i + 1] | params[i + 2] << 8,
                            bytes(params[i + 5:i + 5 + n])))
                i += 5 + n
        return out
