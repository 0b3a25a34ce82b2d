"""One emulated XL430-W250-T: control table, Protocol 2.0 instructions, hardware errors.

The X-series counterpart of hil/servobus/ax12_servo.py, on the same seams: an ``Actuator``
(hil/servobus/drive.py: kinematic, or a MuJoCo joint of the hexapod world) turns the horn,
``ServoHealth`` (hil/servobus/health.py) holds supply, temperature and the overload latch,
faults (hil/servobus/faults.py) reach it through the same methods. The bus (hil/servobus/bus2.py) parses
the line and times the replies; group reads (sync, bulk and their fast forms) are
answered through ``group_read``.

Behaviour follows the ROBOTIS e-manual (XL430-W250-T, Protocol 2.0): operating modes
(velocity, position, extended position, PWM), the trapezoid profile
(hil/servobus/profile.py), torque enable and the EEPROM lock (Access error), Return Delay in
2 us units, Status Return Level, Hardware Error Status with shutdown (torque off until a
reboot). Choices the manual leaves open are marked "our choice" (docs/servo-bus.md).
"""
from __future__ import annotations

import math

from hil.servobus.ax12_servo import EEPROM_BUSY_US
from hil.servobus.drive import Actuator, KinematicActuator, is_moving
from hil.servobus.table_servo import TableServo
from hil.servobus.health import ServoHealth
from hil.servobus.profile import Trapezoid
from protocol.dynamixel import v2 as dx2
from protocol.dynamixel import xl430 as xl

NO_LOAD_RAD_S = xl.NO_LOAD_RPM * 2.0 * math.pi / 60.0   # 57 rpm at 11.1 V (e-manual)
READ_INSTRUCTIONS = (dx2.READ, dx2.SYNC_READ, dx2.FAST_SYNC_READ, dx2.BULK_READ,
                     dx2.FAST_BULK_READ)
# Our choice: the few registers a backup keeps (EEPROM and the gains); "CTRL" key.
BACKUP_RANGES = ((0, xl.EEPROM_END), (76, 92))


class XL430Servo(TableServo):
    """One XL430 on a Protocol 2.0 bus; ``handle`` executes an instruction, returns the reply."""

    model = xl.MODEL_NAME
    layout = xl

    def __init__(self, dev_id: int = 1, actuator: Actuator | None = None,
                 position: int = xl.POSITION_CENTRE, t_us: int = 0,
                 eeprom_busy_us: int = EEPROM_BUSY_US) -> None:
        if not 0 <= dev_id <= dx2.MAX_ID:
            raise ValueError(f"servo id {dev_id} outside 0-{dx2.MAX_ID}")
        self.table = xl.defaults(position)
        self.table[xl.ID] = dev_id
        self.actuator: Actuator = actuator if actuator is not None else \
            KinematicActuator(xl.position_to_rad(position), t_us)
        self.t_us = t_us
        self.t0_us = t_us                      # power-on, for the Realtime Tick
        self.health = ServoHealth()
        self.eeprom_busy_us = eeprom_busy_us
        self.busy_until_us = 0
        self.ignored = 0
        self.instructions = 0
        self.address_changed = False
        self.alarm_led = False
        self.turn_offset = 0                   # pulses taken off by CLEAR (multi-turn)
        self._registered: tuple[int, bytes] | None = None
        self._backup: bytes | None = None
        self._profile: Trapezoid | None = None
        self._command()

    def _get(self, name: str) -> int:
        f = xl.BY_NAME[name]
        return xl.get(self.table, f[0], f[2], f[7])

    def value(self, name: str) -> int:
        """A control-table value by field name (tests, recorder), present values fresh."""
        self._refresh_present()
        return self._get(name)

    @property
    def supply_frac(self) -> float:
        return min(1.0, max(0.0, self.health.supply_v / xl.RATED_SUPPLY_V))

    # --- time, motion, hardware errors --------------------------------------------------
    def advance_to(self, t_us: int) -> None:
        dt_us = t_us - self.t_us
        if dt_us <= 0:
            return
        self.t_us = t_us
        if self._profile is not None and self.torque_on:
            p, _ = self._profile.at(t_us)
            self.actuator.command(p, NO_LOAD_RAD_S * self.supply_frac, self._torque_frac(),
                                  True, self._compliance())
        self.actuator.advance_to(t_us)
        limit = self.table[xl.PWM_LIMIT] | (self.table[xl.PWM_LIMIT + 1] << 8)
        self.health.advance(dt_us, self.actuator.state()[2],
                            (limit * 1023) // xl.PWM_MAX if self.torque_on else 0)
        self._hardware_check()

    def _hardware_check(self) -> None:
        """Latch Hardware Error Status; errors in Shutdown turn the torque off."""
        t = self.table
        v = self.health.voltage_units
        bits = 0
        if v < (t[xl.MIN_VOLTAGE_LIMIT] | t[xl.MIN_VOLTAGE_LIMIT + 1] << 8) or \
                v > (t[xl.MAX_VOLTAGE_LIMIT] | t[xl.MAX_VOLTAGE_LIMIT + 1] << 8):
            bits |= xl.HW_INPUT_VOLTAGE
        if self.health.temperature_units > t[xl.TEMPERATURE_LIMIT]:
            bits |= xl.HW_OVERHEATING
        if self.health.overload:
            bits |= xl.HW_OVERLOAD
        new = bits & ~t[xl.HARDWARE_ERROR_STATUS]
        if not new:
            return
        t[xl.HARDWARE_ERROR_STATUS] |= new
        self.alarm_led = True
        if t[xl.HARDWARE_ERROR_STATUS] & t[xl.SHUTDOWN] and t[xl.TORQUE_ENABLE]:
            t[xl.TORQUE_ENABLE] = 0
            self._command()

    @property
    def shut_down(self) -> bool:
        return bool(self.table[xl.HARDWARE_ERROR_STATUS] & self.table[xl.SHUTDOWN])

    def _present_pulses(self, angle_rad: float) -> int:
        return xl.rad_to_position(angle_rad) - self.turn_offset

    def _refresh_present(self) -> None:
        pos, vel, load = self.actuator.state()
        t = self.table
        traj_p, traj_v = (self._profile.at(self.t_us) if self._profile is not None
                          else (pos, vel))
        xl.put(t, xl.PRESENT_POSITION, 4, self._present_pulses(pos))
        xl.put(t, xl.PRESENT_VELOCITY, 4, xl.rad_s_to_velocity(vel))
        xl.put(t, xl.PRESENT_LOAD, 2, int(round(max(-1.0, min(1.0, load)) * 1000)))
        xl.put(t, xl.PRESENT_PWM, 2, int(round(max(-1.0, min(1.0, load)) * xl.PWM_MAX)))
        xl.put(t, xl.POSITION_TRAJECTORY, 4, self._present_pulses(traj_p))
        xl.put(t, xl.VELOCITY_TRAJECTORY, 4, xl.rad_s_to_velocity(traj_v))
        xl.put(t, xl.PRESENT_INPUT_VOLTAGE, 2, self.health.voltage_units)
        t[xl.PRESENT_TEMPERATURE] = self.health.temperature_units
        moving = is_moving(vel)
        t[xl.MOVING] = 1 if moving else 0
        t[xl.MOVING_STATUS] = (0x02 if moving else 0) | (0x01 if self._arrived(pos) else 0)
        xl.put(t, xl.REALTIME_TICK, 2, ((self.t_us - self.t0_us) // 1000) % 32768)
        t[xl.BACKUP_READY] = 1 if self._backup is not None else 0

    def _arrived(self, pos: float) -> bool:
        goal = self._get("goal_position")
        return abs(self._present_pulses(pos) - goal) <= 1

    def state_errors(self) -> int:
        """Hardware Error Status (what the recorder logs as the servo's error)."""
        return self.table[xl.HARDWARE_ERROR_STATUS]

    # --- the drive ----------------------------------------------------------------------
    def _torque_frac(self) -> float:
        t = self.table
        return (t[xl.PWM_LIMIT] | (t[xl.PWM_LIMIT + 1] << 8)) / xl.PWM_MAX * self.supply_frac

    def _compliance(self) -> tuple[float, float, float, float, float]:
        """The P gain as the drive seam's compliance: duty reaches 100 % at an error of
        PWM_MAX * 128 / KPP pulses (e-manual control block: PWM = KPP / 128 * error), given
        in AX-12 position units (0.29 deg) as the seam takes them."""
        kpp = max(1, self._get("position_p_gain"))
        slope_units = xl.PWM_MAX * 128.0 / kpp * xl.RAD_PER_PULSE / math.radians(300.0 / 1023)
        return (0.0, 0.0, slope_units, slope_units, 0.0)

    def _command(self) -> None:
        """Hand the set-point of the present operating mode to the actuator."""
        t = self.table
        mode = t[xl.OPERATING_MODE]
        no_load = NO_LOAD_RAD_S * self.supply_frac
        torque = self._torque_frac()
        enabled = self.torque_on
        pos = self.actuator.state()[0]
        self._profile = None
        if mode == xl.MODE_VELOCITY:
            v = xl.velocity_to_rad_s(self._get("goal_velocity"))
            goal = math.inf if v > 0 else (-math.inf if v < 0 else pos)
            self.actuator.command(goal, min(abs(v), no_load), torque, enabled, self._compliance())
            return
        if mode == xl.MODE_PWM:
            duty = self._get("goal_pwm") / xl.PWM_MAX
            goal = math.inf if duty > 0 else (-math.inf if duty < 0 else pos)
            self.actuator.command(goal, abs(duty) * no_load, min(abs(duty), torque), enabled,
                                  self._compliance())
            return
        goal_p = self._get("goal_position") + self.turn_offset
        if mode == xl.MODE_POSITION:
            lo, hi = self._get("min_position_limit"), self._get("max_position_limit")
            goal_p = lo if goal_p < lo else (hi if goal_p > hi else goal_p)
        goal = xl.position_to_rad(goal_p)
        vel = self._get("profile_velocity")
        acc = self._get("profile_acceleration")
        vmax = xl.velocity_to_rad_s(vel) if vel else math.inf
        if acc and enabled:   # streamed set-points along the trapezoid (advance_to)
            self._profile = Trapezoid(self.t_us, pos, goal, self.actuator.state()[1], vmax,
                                      xl.acceleration_to_rad_s2(acc))
            goal = self._profile.at(self.t_us)[0]
            vmax = math.inf
        self.actuator.command(goal, min(vmax, no_load), torque, enabled, self._compliance())

    # --- faults (hil/servobus/faults.py) -----------------------------------------------------------
    def set_supply_v(self, volts: float, t_us: int) -> None:
        self.advance_to(t_us)
        self.health.set_supply_v(volts)
        self._hardware_check()
        self._command()

    def set_stalled(self, stalled: bool, t_us: int) -> None:
        self.advance_to(t_us)
        fn = getattr(self.actuator, "set_stalled", None)
        if fn is not None:
            fn(stalled)

    def power_cycle(self, t_us: int) -> None:
        """Power lost and back (or REBOOT): RAM to defaults, EEPROM kept, errors cleared."""
        self.advance_to(t_us)
        eeprom = bytes(self.table[:xl.EEPROM_END])
        pos = xl.rad_to_position(self.actuator.state()[0])
        self.table = xl.defaults(pos)
        self.table[:xl.EEPROM_END] = eeprom
        self.t0_us = t_us
        self.turn_offset = 0
        self.health.rearm()
        self.alarm_led = False
        self._registered = None
        self._command()

    # --- instructions -------------------------------------------------------------------
    def _error_field(self, error: int) -> int:
        return error | (dx2.ALERT if self.table[xl.HARDWARE_ERROR_STATUS] else 0)

    def _answer(self, instr: int, error: int, params: bytes = b"") -> bytes | None:
        srl = self.table[xl.STATUS_RETURN_LEVEL]
        if srl >= 2 or instr == dx2.PING or (srl == 1 and instr in READ_INSTRUCTIONS):
            return dx2.status(self.id, self._error_field(error), params)
        return None

    def ping_reply(self) -> bytes:
        """PING is answered at every Status Return Level (e-manual)."""
        return dx2.status(self.id, self._error_field(0),
                          bytes((xl.MODEL_NUMBER & 0xFF, xl.MODEL_NUMBER >> 8,
                                 xl.FIRMWARE_VERSION)))

    def read_block(self, address: int, length: int) -> tuple[int, bytes]:
        """(error number, data) of a READ; the data is zeros where refused (our choice,
        so a group read keeps its shape)."""
        if length == 0 or address + length > xl.TABLE_SIZE:
            return dx2.ERR_ACCESS, bytes(length)
        self._refresh_present()
        return 0, bytes(self.table[address:address + length])

    def group_read(self, address: int, length: int, t_us: int) -> tuple[int, bytes] | None:
        """This servo's part of a sync/bulk read: (error field, data), or None (silent:
        deaf, or Status Return Level 0)."""
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
            self.busy_until_us = t_us + self.eeprom_busy_us
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
        if start == xl.OPERATING_MODE and v not in xl.MODES:
            return dx2.ERR_DATA_RANGE
        if start == xl.BAUD_RATE and v >= len(xl.BAUD_BPS):
            return dx2.ERR_DATA_RANGE
        if start == xl.TORQUE_ENABLE and v and self.shut_down:
            return dx2.ERR_RESULT_FAIL   # our choice: shut down until a reboot
        if start == xl.GOAL_POSITION and t[xl.OPERATING_MODE] == xl.MODE_POSITION and not \
                self._get("min_position_limit") <= v <= self._get("max_position_limit"):
            return dx2.ERR_DATA_LIMIT
        if start == xl.GOAL_VELOCITY and abs(v) > self._get("velocity_limit"):
            return dx2.ERR_DATA_LIMIT
        if start == xl.GOAL_PWM and abs(v) > self._get("pwm_limit"):
            return dx2.ERR_DATA_LIMIT
        return 0

    def _apply_write(self, address: int, data: bytes) -> None:
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
        keep_id, keep_baud = self.table[xl.ID], self.table[xl.BAUD_RATE]
        pos = xl.rad_to_position(self.actuator.state()[0])
        self.table = xl.defaults(pos)
        if option != dx2.RESET_ALL:
            self.table[xl.ID] = keep_id
        if option == dx2.RESET_EXCEPT_ID_BAUD:
            self.table[xl.BAUD_RATE] = keep_baud
        self.busy_until_us = self.t_us + self.eeprom_busy_us
        self._registered = None
        self.turn_offset = 0
        self.health.rearm()
        self.alarm_led = False
        self.address_changed = True
        self._command()

    def _clear(self, key: bytes) -> int:
        if key != dx2.CLEAR_MULTI_TURN:
            return dx2.ERR_DATA_RANGE
        if self.moving:
            return dx2.ERR_RESULT_FAIL   # e-manual: only while stopped
        p = self._present_pulses(self.actuator.state()[0])
        self.turn_offset += p - p % xl.PULSES_PER_REV
        return 0

    def _backup_cmd(self, key: bytes) -> int:
        if key == dx2.BACKUP_STORE:
            self._backup = b"".join(bytes(self.table[a:b]) for a, b in BACKUP_RANGES)
            return 0
        if key != dx2.BACKUP_RESTORE:
            return dx2.ERR_DATA_RANGE
        if self._backup is None:
            return dx2.ERR_RESULT_FAIL
        if self.torque_on:
            return dx2.ERR_ACCESS
        i = 0
        for a, b in BACKUP_RANGES:
            self.table[a:b] = self._backup[i:i + b - a]
            i += b - a
        self.address_changed = True
        self._command()
        return 0
