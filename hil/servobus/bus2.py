"""The half-duplex line of hil/servobus/line.py carrying Protocol 2.0 (X-series servos).

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

from hil.servobus.line import Bus, _Burst, resample
from protocol.dynamixel import v2 as dx2

GROUP_READS = (dx2.SYNC_READ, dx2.FAST_SYNC_READ, dx2.BULK_READ, dx2.FAST_BULK_READ)


class Bus2(Bus):
    """A Protocol 2.0 line: servos with ``handle``/``group_read`` (hil/servobus/xl430_servo.py)."""

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
        """Put a reply on the line from ``start_us``; when it ends (even if lost)."""
        data = bytearray(reply)
        end = start_us + self.wire_us(len(data))
        faults = self.faults
        if faults is not None:
            if faults.drop_status(s.id, start_us):
                return end
            faults.corrupt(data, start_us, "rx")
        self.stats["replies"] += 1
        self._put(_Burst(start_us, data, True))
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
