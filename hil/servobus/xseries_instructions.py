"""The Protocol 2.0 instructions an X-series servo executes (hil/servobus/xseries_servo.py):
PING, READ and the group reads' parts, WRITE/REG_WRITE/ACTION, SYNC and BULK WRITE, FACTORY
RESET, REBOOT, CLEAR and the control-table backup, each checked against the model's table
(``layout``) as the e-manual says; the bus (hil/servobus/protocols/v2.py) times the replies.
"""
from __future__ import annotations

from hexhil.hil.servobus.table_servo import TableServo
from hexhil.protocol.dynamixel import v2 as dx2

READ_INSTRUCTIONS = (dx2.READ, dx2.SYNC_READ, dx2.FAST_SYNC_READ, dx2.BULK_READ,
                     dx2.FAST_BULK_READ)
GAINS = (76, 92)   # our choice: a backup keeps the EEPROM and the gains ("CTRL" key)


class XSeriesInstructions(TableServo):
    """The instruction set over XSeriesServo's state (its table, motion and health:
    ``_get``, ``_command``, ``_refresh_present``, ``_present_pulses``, ``power_cycle``)."""

    t_us: int
    eeprom_busy_us: int
    address_changed: bool
    alarm_led: bool
    turn_offset: int
    _backup: bytes | None

    # --- replies -------------------------------------------------------------------
    def _error_field(self, error: int) -> int:
        xl = self.layout
        return error | (dx2.ALERT if self.table[xl.HARDWARE_ERROR_STATUS] else 0)

    def _answer(self, instr: int, error: int, params: bytes = b"") -> bytes | None:
        xl = self.layout
        srl = self.table[xl.STATUS_RETURN_LEVEL]
        if srl >= 2 or instr == dx2.PING or (srl == 1 and instr in READ_INSTRUCTIONS):
            return dx2.status(self.id, self._error_field(error), params)
        return None

    def ping_reply(self) -> bytes:
        """PING is answered at every Status Return Level (e-manual)."""
        xl = self.layout
        return dx2.status(self.id, self._error_field(0),
                          bytes((xl.MODEL_NUMBER & 0xFF, xl.MODEL_NUMBER >> 8,
                                 xl.FIRMWARE_VERSION)))

    def read_block(self, address: int, length: int) -> tuple[int, bytes]:
        """(error number, data) of a READ; the data is zeros where refused (our choice,
        so a group read keeps its shape)."""
        xl = self.layout
        if length == 0 or address + length > xl.TABLE_SIZE:
            return dx2.ERR_ACCESS, bytes(length)
        self._refresh_present()
        return 0, bytes(self.table[address:address + length])

    def group_read(self, address: int, length: int, t_us: int) -> tuple[int, bytes] | None:
        """This servo's part of a sync/bulk read: (error field, data), or None (silent:
        deaf, or Status Return Level 0)."""
        xl = self.layout
        self.advance_to(t_us)
        if self._deaf(t_us) or self.table[xl.STATUS_RETURN_LEVEL] == 0:
            return None
        self.instructions += 1
        error, data = self.read_block(address, length)
        return self._error_field(error), data

    def handle(self, instr: int, params: bytes, broadcast: bool, t_us: int) -> bytes | None:
        """Execute one instruction at t_us; return the status packet, or None."""
        if not self._take(t_us):
            return None
        if instr == dx2.PING:
            return self.ping_reply()
        error, data = 0, b""
        if instr == dx2.READ:
            if len(params) != 4:
                error = dx2.ERR_DATA_LENGTH
            else:
                error, data = self.read_block(params[0] | params[1] << 8,
                                              params[2] | params[3] << 8)
                data = b"" if error else data
        elif instr in (dx2.WRITE, dx2.REG_WRITE):
            if len(params) < 3:
                error = dx2.ERR_DATA_LENGTH
            else:
                a, d = params[0] | params[1] << 8, bytes(params[2:])
                error = self.check_write(a, d)
                if not error:
                    self._write_or_register(instr == dx2.WRITE, a, d)
        elif instr == dx2.ACTION:
            registered = self._take_registered()
            if registered is None:
                error = dx2.ERR_INSTRUCTION
            else:
                error = self.check_write(*registered)
                if not error:
                    self._apply_write(*registered)
        elif instr == dx2.SYNC_WRITE:
            self._sync_write(params)
            return None
        elif instr == dx2.BULK_WRITE:
            self._bulk_write(params)
            return None
        elif instr == dx2.FACTORY_RESET:
            option = params[0] if len(params) == 1 else -1
            if option not in (dx2.RESET_ALL, dx2.RESET_EXCEPT_ID, dx2.RESET_EXCEPT_ID_BAUD):
                error = dx2.ERR_DATA_RANGE
            elif broadcast and option == dx2.RESET_ALL:
                return None   # e-manual: not activated for broadcast with Reset All
            elif self.torque_on:
                error = dx2.ERR_ACCESS  # it rewrites EEPROM (our choice: same lock)
            else:
                reply = None if broadcast else self._answer(instr, 0)
                self._factory_reset(option)
                return reply
        elif instr == dx2.REBOOT:
            reply = None if broadcast else self._answer(instr, 0)
            self.power_cycle(t_us)
            self.deaf_until_us = t_us + self.eeprom_busy_us
            return reply
        elif instr == dx2.CLEAR:
            error = self._clear(bytes(params))
        elif instr == dx2.CONTROL_TABLE_BACKUP:
            error = self._backup_cmd(bytes(params))
        else:
            error = dx2.ERR_INSTRUCTION
        if broadcast:
            return None
        return self._answer(instr, error, data)

    def _sync_write(self, params: bytes) -> None:
        if len(params) < 4:
            return
        a, n = params[0] | params[1] << 8, params[2] | params[3] << 8
        stride = n + 1
        if n == 0 or (len(params) - 4) % stride:
            return
        for i in range(4, len(params), stride):
            if params[i] == self.id:
                d = bytes(params[i + 1:i + stride])
                if not self.check_write(a, d):
                    self._apply_write(a, d)
                return

    def _bulk_write(self, params: bytes) -> None:
        i = 0
        while i + 5 <= len(params):
            dev, a, n = params[i], params[i + 1] | params[i + 2] << 8, params[i + 3] | params[i + 4] << 8
            d = bytes(params[i + 5:i + 5 + n])
            if dev == self.id and len(d) == n and not self.check_write(a, d):
                self._apply_write(a, d)
            i += 5 + n

    def check_write(self, address: int, data: bytes) -> int:
        """The error number a WRITE of ``data`` at ``address`` earns (0: accepted)."""
        xl = self.layout
        end = address + len(data)
        if end > xl.TABLE_SIZE:
            return dx2.ERR_ACCESS
        if address < xl.EEPROM_END and self.torque_on:
            return dx2.ERR_ACCESS  # EEPROM is locked while the torque is on
        t = self.table
        a = address
        while a < end:
            f = xl.OWNER[a]
            if f is None or f[3] == xl.R:
                return dx2.ERR_ACCESS
            start, size = f[0], f[2]
            if start < address or start + size > end:
                return dx2.ERR_DATA_LENGTH
            v = xl.get(data, start - address, size, f[7])
            if v < f[5] or v > f[6]:
                return dx2.ERR_DATA_RANGE
            error = self._check_value(start, v, t)
            if error:
                return error
            a = start + size
        return 0

    def _check_value(self, start: int, v: int, t: bytearray) -> int:
        xl = self.layout
        if start == xl.OPERATING_MODE and v not in xl.MODES:
            return dx2.ERR_DATA_RANGE
        if start == xl.BAUD_RATE and v >= len(xl.BAUD_BPS):
            return dx2.ERR_DATA_RANGE
        if start == xl.TORQUE_ENABLE and v and self.shut_down:
            return dx2.ERR_RESULT_FAIL   # our choice: shut down until a reboot
        if start == xl.GOAL_POSITION and t[xl.OPERATING_MODE] in xl.LIMITED_POSITION_MODES and not \
                self._get("min_position_limit") <= v <= self._get("max_position_limit"):
            return dx2.ERR_DATA_LIMIT
        if start == xl.GOAL_VELOCITY and abs(v) > self._get("velocity_limit"):
            return dx2.ERR_DATA_LIMIT
        if start == xl.GOAL_PWM and abs(v) > self._get("pwm_limit"):
            return dx2.ERR_DATA_LIMIT
        if xl.CURRENT_MODES and start == xl.GOAL_CURRENT and abs(v) > self._get("current_limit"):
            return dx2.ERR_DATA_LIMIT
        return 0

    def _apply_write(self, address: int, data: bytes) -> None:
        xl = self.layout
        t = self.table
        end = address + len(data)
        if address <= xl.OPERATING_MODE < end and data[xl.OPERATING_MODE - address] \
                != t[xl.OPERATING_MODE]:
            self.turn_offset = 0
            pos = self._present_pulses(self.actuator.state()[0])
            xl.put(t, xl.GOAL_POSITION, 4, pos)   # a new mode holds where it is
        t[address:end] = data
        if address < xl.EEPROM_END:
            self.busy_until_us = self.t_us + self.eeprom_busy_us
        if address <= xl.BAUD_RATE and end > xl.ID:
            self.address_changed = True
        if end > xl.OPERATING_MODE and address < xl.EEPROM_END or \
                end > xl.TORQUE_ENABLE and address < xl.REALTIME_TICK:
            self._command()

    def _factory_reset(self, option: int) -> None:
        xl = self.layout
        keep_id, keep_baud = self.table[xl.ID], self.table[xl.BAUD_RATE]
        pos = xl.rad_to_position(self.actuator.state()[0])
        self.table = xl.defaults(pos)
        if option != dx2.RESET_ALL:
            self.table[xl.ID] = keep_id
        if option == dx2.RESET_EXCEPT_ID_BAUD:
            self.table[xl.BAUD_RATE] = keep_baud
        self.deaf_until_us = self.t_us + self.eeprom_busy_us
        self._registered = None
        self.turn_offset = 0
        self.health.rearm()
        self.alarm_led = False
        self.address_changed = True
        self._command()

    def _clear(self, key: bytes) -> int:
        xl = self.layout
        if key != dx2.CLEAR_MULTI_TURN:
            return dx2.ERR_DATA_RANGE
        if self.moving:
            return dx2.ERR_RESULT_FAIL   # e-manual: only while stopped
        p = self._present_pulses(self.actuator.state()[0])
        self.turn_offset += p - p % xl.PULSES_PER_REV
        return 0

    def _backup_cmd(self, key: bytes) -> int:
        if key == dx2.BACKUP_STORE:
            self._backup = b"".join(bytes(self.table[a:b]) for a, b in self._backup_ranges())
            return 0
        if key != dx2.BACKUP_RESTORE:
            return dx2.ERR_DATA_RANGE
        if self._backup is None:
            return dx2.ERR_RESULT_FAIL
        if self.torque_on:
            return dx2.ERR_ACCESS
        i = 0
        for a, b in self._backup_ranges():
            self.table[a:b] = self._backup[i:i + b - a]
            i += b - a
        self.address_changed = True
        self._command()
        return 0

    def _backup_ranges(self) -> tuple[tuple[int, int], ...]:
        return ((0, self.layout.EEPROM_END), GAINS)
