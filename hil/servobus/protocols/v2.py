"""Protocol 2.0 on the servo bus: the line's packet layer, the X-series servo a model's
table makes, and the master check's rules (hil/servobus/master_check.py).

The line is hil/servobus/line.py's half-duplex line carrying Protocol 2.0.

Everything about the wire is inherited: virtual-time byte timing, the wired-AND
collisions, echo, servos at another baud (``resample``), line faults and the timed
faults. What differs is the packet layer: a Protocol 2.0 parser, packets with a bad CRC
dropped without a reply (no status can be trusted to an ID whose packet failed its CRC),
and the group reads that several servos answer in turn:

- SYNC_READ / BULK_READ: each listed servo sends its own status packet, in the order of
  the list, its Return Delay after the previous one has finished (e-manual: each device
  waits for the status packet of the one before it);
- FAST_SYNC_READ / FAST_BULK_READ: ONE status packet (ID 0xFE); the first listed servo
  starts it after its Return Delay, every next one appends its block at once;
- broadcast PING: every servo answers, in ID order, chained the same way.

Our choice where the manual is silent: a listed servo that stays silent (absent,
unplugged, deaf, Status Return Level 0) ends the chain: the ones after it wait for a
status packet that never comes and send nothing.
"""
from __future__ import annotations

from types import ModuleType
from typing import TYPE_CHECKING

from hexhil.hil.scenario import BusConfig
from hexhil.hil.servobus.drive import Actuator
from hexhil.hil.servobus.line import Bus
from hexhil.hil.servobus.packet_check import OnViolation, PacketCheck
from hexhil.hil.servobus.wire import Burst, resample
from hexhil.hil.servobus.xseries_servo import XSeriesServo
from hexhil.protocol.dynamixel import v2 as dx2
from hexhil.protocol.errors import BadValue

if TYPE_CHECKING:
    from hexhil.hil.servobus.line import Bus

GROUP_READS = (dx2.SYNC_READ, dx2.FAST_SYNC_READ, dx2.BULK_READ, dx2.FAST_BULK_READ)


class Bus2(Bus):
    """A Protocol 2.0 line: servos with ``handle``/``group_read`` (hil/servobus/xseries_servo.py)."""

    protocol = 2
    parser_class = dx2.Parser

    def add_device(self, device) -> None:
        raise ValueError("a Protocol 2.0 bus takes X-series servos only")

    def _deliver(self, tx: bytearray, t_us: int) -> None:
        parser = self._parser
        bad = parser.bad_crc
        for byte in tx:
            if parser.push(byte, t_us):
                self.stats["packets"] += 1
                params = bytes(parser.buf[dx2.PARAMS_OFFSET:dx2.PARAMS_OFFSET + parser.nparams])
                self._dispatch(parser.id, parser.instr, params, t_us)
            elif parser.bad_crc != bad:
                bad = parser.bad_crc
                self.stats["bad_checksum"] += 1

    def _live(self, dev_id: int) -> list:
        return [s for s in self._by_id.get(dev_id, ()) if id(s) not in self._off]

    def _dispatch(self, dev_id: int, instr: int, params: bytes, t_us: int) -> None:
        if instr == dx2.STATUS:
            return
        if instr in GROUP_READS:
            if dev_id == dx2.BROADCAST_ID:
                self._group_read(instr, params, t_us)
        elif instr == dx2.PING and dev_id == dx2.BROADCAST_ID:
            self._broadcast_ping(t_us)
        else:
            targets = [s for s in self._same if id(s) not in self._off] \
                if dev_id == dx2.BROADCAST_ID else self._live(dev_id)
            for s in targets:
                reply = s.handle(instr, params, dev_id == dx2.BROADCAST_ID, t_us)
                if reply is not None:
                    self._send(s, reply, t_us + s.return_delay_us)
        if any(s.address_changed for s in self.servos):
            self._reindex()

    def _requests(self, instr: int, params: bytes) -> list[tuple[int, int, int]]:
        """(id, address, length) of each servo a group read lists, in order."""
        if instr in (dx2.SYNC_READ, dx2.FAST_SYNC_READ):
            if len(params) < 5:
                return []
            a, n = params[0] | params[1] << 8, params[2] | params[3] << 8
            return [(i, a, n) for i in params[4:]]
        if len(params) % 5:
            return []
        return [(params[i], params[i + 1] | params[i + 2] << 8, params[i + 3] | params[i + 4] << 8)
                for i in range(0, len(params), 5)]

    def _group_read(self, instr: int, params: bytes, t_us: int) -> None:
        fast = instr in (dx2.FAST_SYNC_READ, dx2.FAST_BULK_READ)
        blocks: list[tuple[int, int, bytes]] = []
        first = None
        end_us = t_us
        for dev_id, address, length in self._requests(instr, params):
            found = self._live(dev_id)
            part = found[0].group_read(address, length, t_us) if found else None
            if part is None:
                break                                   # the chain stops here
            s = found[0]
            if fast:
                first = s if first is None else first
                blocks.append((part[0], dev_id, part[1]))
            else:
                reply = dx2.status(dev_id, part[0], part[1])
                start = end_us + s.return_delay_us
                end_us = self._send(s, reply, start)
        if fast and blocks:
            self._send(first, dx2.fast_status(blocks), t_us + first.return_delay_us)

    def _broadcast_ping(self, t_us: int) -> None:
        end_us = t_us
        for s in sorted((s for s in self._same if id(s) not in self._off), key=lambda s: s.id):
            s.advance_to(t_us)
            if s._deaf(t_us):
                break
            end_us = self._send(s, s.ping_reply(), end_us + s.return_delay_us)

    def _send(self, s, reply: bytes, start_us: int) -> int:
        """Put a reply on the line from ``start_us``, as the status faults active on ``s``
        send it (none, one, late, mangled, or a twin's too: ``[faults] status_*``); when
        it would have ended: the next servo of a group read answers after that, as ever."""
        data = bytearray(reply)
        wire_us = self.wire_us(len(data))
        end = start_us + wire_us
        faults = self.faults
        bursts = [(start_us, data)]
        if faults is not None:
            if faults.drop_status(s.id, start_us):
                return end
            faults.corrupt(data, start_us, "rx")
            bursts = faults.status_bursts(s.id, data, start_us, wire_us, self.protocol)
        for t, burst in bursts:
            self.stats["replies"] += 1
            self._put(Burst(t, burst, True))
        return end

    def _deliver_foreign(self, s, parser: dx2.Parser, tx: bytearray, t_us: int) -> None:
        """A servo at another baud decodes the line with its own UART timing."""
        for byte in resample(tx, self.baud, s.baud_bps):
            if not parser.push(byte, t_us):
                continue
            dev_id = parser.id
            if dev_id != s.id and dev_id != dx2.BROADCAST_ID or parser.instr in GROUP_READS \
                    or parser.instr == dx2.STATUS:
                continue
            params = bytes(parser.buf[dx2.PARAMS_OFFSET:dx2.PARAMS_OFFSET + parser.nparams])
            reply = s.handle(parser.instr, params, dev_id == dx2.BROADCAST_ID, t_us)
            if reply is not None:
                self._send(s, resample(reply, s.baud_bps, self.baud), t_us + s.return_delay_us)
            if s.address_changed:
                self._reindex()
                return


def make_servo(layout: ModuleType, dev_id: int, actuator: Actuator | None,
               bus: BusConfig) -> XSeriesServo:
    """An X-series servo of the model whose table is ``layout``, set up as ``bus`` says
    (Return Delay, Baud Rate; the horn where the actuator is)."""
    if dev_id > dx2.MAX_ID:                 # IDs given apart from the scenario (hexhil bus --ids)
        raise BadValue(f"servo ID {dev_id}: an {layout.MODEL_NAME} takes IDs 0-{dx2.MAX_ID}")
    x = XSeriesServo(dev_id, actuator=actuator, eeprom_busy_us=bus.eeprom_busy_us, position=(
        layout.rad_to_position(actuator.state()[0]) if actuator is not None
        else layout.POSITION_CENTRE), layout=layout)
    x.table[layout.RETURN_DELAY_TIME] = (500 if bus.return_delay_us is None
                                         else bus.return_delay_us) // 2
    x.table[layout.BAUD_RATE] = layout.bps_to_baud(bus.baud)
    return x


class Packet2Check(PacketCheck):
    """The X-series rules (Protocol 2.0)."""

    def __init__(self, flag: OnViolation) -> None:
        PacketCheck.__init__(self, flag, dx2.Parser())

    def bad(self) -> int:
        return self.parser.bad_crc

    def bad_detail(self) -> str:
        return f"bad CRC in a packet to id {self.parser.last_bad_crc_id}"

    def packet(self, bus: Bus, t_us: int) -> None:
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
