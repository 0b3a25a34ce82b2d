"""Protocol 1.0 on the servo bus: the AX-12 a model's table makes (the line is
hil/servobus/line.py's ``Bus``) and the master check's rules (hil/servobus/master_check.py)."""
from __future__ import annotations

from types import ModuleType
from typing import TYPE_CHECKING

from hexhil.hil.scenario import BusConfig
from hexhil.hil.servobus.ax12_servo import Servo
from hexhil.hil.servobus.drive import Actuator
from hexhil.hil.servobus.packet_check import OnViolation, PacketCheck
from hexhil.protocol.dynamixel import v1 as dxl

if TYPE_CHECKING:
    from hexhil.hil.servobus.line import Bus


def make_servo(layout: ModuleType, dev_id: int, actuator: Actuator | None,
               bus: BusConfig) -> Servo:
    """An AX-12 set up as ``bus`` says (manual edition, Return Delay, the Baud Rate register
    of the line's rate, checked by the scenario; the horn where the actuator is)."""
    pos = layout.rad_to_position(actuator.state()[0]) if actuator is not None else 512
    s = Servo(dev_id, bus.edition, actuator=actuator, position=pos,
              eeprom_busy_us=bus.eeprom_busy_us)
    if bus.return_delay_us is not None:
        s.table[layout.RETURN_DELAY_TIME] = bus.return_delay_us // 2
    s.table[layout.BAUD_RATE] = layout.bps_to_baud(bus.baud)
    return s


class Packet1Check(PacketCheck):
    """The AX-12 rules (Protocol 1.0)."""

    def __init__(self, flag: OnViolation) -> None:
        PacketCheck.__init__(self, flag, dxl.Parser())

    def bad(self) -> int:
        return self.parser.bad_checksum

    def bad_detail(self) -> str:
        return f"packet to id {self.parser.last_bad_checksum_id}"

    def packet(self, bus: Bus, t_us: int) -> None:
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
