"""One emulated AX-12A: control table, every instruction, error bits, alarms.

The servo owns its 50-byte control table (``protocol/dynamixel/ax12.py``), executes instructions
against it and drives an ``Actuator`` (hil/servobus/drive.py), the seam to whatever moves
the horn: ``KinematicActuator`` (no physics) or a MuJoCo joint in the hexapod world.
Supply, temperature and overload live in ``ServoHealth`` (hil/servobus/health.py); the
servo turns their error bits into the Alarm LED and alarm shutdown.

State is evaluated lazily: the bus calls ``advance_to(t_us)`` before a servo answers,
and the kinematic model is integrated exactly over any interval in which the command
is constant, so lazy and stepped evaluation give the same table.

Behaviour follows the ROBOTIS e-manual (AX-12A, Protocol 1.0) and the original AX-12
manual (2006) where they differ (defaults, Lock). Choices the manuals leave open are
marked "our choice" and listed in docs/servo-bus.md.
"""
from __future__ import annotations

import ctypes

from hexhil.hil.servobus.drive import Actuator, KinematicActuator, drive
from hexhil.hil.servobus.table_servo import TableServo
from hexhil.hil.servobus import servo_rules
from hexhil.hil.servobus.health import ServoHealth
from hexhil.hil.servobus.servo_layout import APPLY_COMMAND, READ_COMMAND, READ_REFRESH, SERVO
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl

class Servo(TableServo, ctypes.Structure):
    """One AX-12A on the bus; ``handle`` takes a parsed instruction and returns the reply.

    ``handle``/``checksum_error`` return the status packet to send (bytes) or None; the
    bus adds the return delay and wire time. ``instructions`` counts packets executed.

    Its clock, counters and flags are ctypes fields (and its table keeps its buffer: a
    reset rewrites it in place), so the compiled SYNC_WRITE (hil/servobus/servo_core.c,
    ``struct servo``) steps the same state this class does.
    """

    _fields_ = SERVO   # servo_layout.py: the C code's ``struct servo`` too
    layout = ax12

    def __init__(self, dev_id: int = 1, edition: str = ax12.EDITION_EMANUAL,
                 actuator: Actuator | None = None, position: int = 512, t_us: int = 0,
                 eeprom_busy_us: int | None = None) -> None:
        if edition not in ax12.EDITIONS:
            raise ValueError(f"unknown AX-12 manual edition {edition!r}")
        if not 0 <= dev_id <= dxl.MAX_ID:
            raise ValueError(f"servo id {dev_id} outside 0-{dxl.MAX_ID}")
        self.edition = edition
        self.table = ax12.defaults(edition, position)
        self.table[ax12.ID] = dev_id
        self._table_view, self._table_at = servo_rules.address(self.table)   # for servo_rules
        self._at = ctypes.addressof(self)
        self._calls = servo_rules.ServoCalls()
        self.actuator: Actuator = actuator if actuator is not None else \
            KinematicActuator(ax12.position_to_rad(position), t_us)
        self.t_us = t_us
        self.health = ServoHealth()
        self._registered: tuple[int, bytes] | None = None
        self.alarm_led = False                 # the LED blinks for errors in Alarm LED
        self.address_changed = False           # ID or Baud Rate written: bus re-indexes
        self.instructions = 0
        # busy this long after an EEPROM write (a packet then waits: docs/servo-bus.md)
        self.eeprom_busy_us = ax12.EEPROM_BUSY_US if eeprom_busy_us is None else eeprom_busy_us
        self.busy_until_us = 0                 # an EEPROM write under way until then
        self.deaf_until_us = 0                 # rebooting (factory reset) until then
        self.ignored = 0                       # packets that arrived while deaf
        self.held = self.held_us = 0           # packets that waited for an EEPROM write
        self._command()
        self._present_stale = True

    def value(self, name: str) -> int:
        """A control-table value by field name (tests, recorder)."""
        f = ax12.BY_NAME[name]
        return ax12.get(self._present(), f[0], f[2])

    # --- time, motion, alarms ---------------------------------------------------------
    def advance_to(self, t_us: int) -> None:
        """Bring motion, temperature, voltage and alarms up to virtual time t_us."""
        dt_us = t_us - self.t_us
        if dt_us <= 0:
            return
        self.t_us = t_us
        act = self.actuator
        act.advance_to(t_us)
        # the health's step against the Torque Limit, its errors and their alarms
        if servo_rules.catch_up(self._at, self.health.at, self._table_at, dt_us, act.state()[2]):
            self._command()

    def _present(self) -> bytearray:
        """The control table with Present Position..Moving brought up to date: they are
        computed when read, not after every motion step (a walking run reads 3 of 18
        servos a cycle)."""
        if self._present_stale:
            self._refresh_present()
        return self.table

    def _refresh_present(self) -> None:
        self._present_stale = False
        p = servo_rules.present(self._table_at, self.health.at, *self.actuator.state())
        if self.reading is not None:   # a Present Position fault reads the true value its way
            p = max(0, min(1023, self._position_read(p)))
            self.table[ax12.PRESENT_POSITION] = p & 0xFF
            self.table[ax12.PRESENT_POSITION + 1] = p >> 8

    def state_row(self) -> tuple:
        """The recorder's row (the compiled rule, as the line's bank packs it)."""
        return self._calls.state_row(self._table_at, self.health.at, self.actuator.state())

    def state_errors(self) -> int:
        """Error bits that describe the servo's state (voltage, heat, overload)."""
        return self.health.errors(self._table_at)

    def _alarm(self, errors: int) -> None:
        """Alarm LED and alarm shutdown: Torque Limit drops to 0 (e-manual, address 34)."""
        if servo_rules.alarm(self._at, self._table_at, errors):
            self._command()

    def _command(self) -> None:
        drive(self.actuator, self._calls.setpoint(self._table_at, self.health.supply_frac))

    # --- faults (hil/servobus/faults.py) -----------------------------------------------------
    def set_supply_v(self, volts: float, t_us: int) -> None:
        self.advance_to(t_us)
        self.health.set_supply_v(volts)
        self._command()
        self._present_stale = True

    def set_stalled(self, stalled: bool, t_us: int) -> None:
        """External load blocks the horn (actuators without ``set_stalled`` ignore it)."""
        self.advance_to(t_us)
        fn = getattr(self.actuator, "set_stalled", None)
        if fn is not None:
            fn(stalled)
            self._present_stale = True

    def power_cycle(self, t_us: int) -> None:
        """Power lost and back (a plug pulled): RAM to defaults, EEPROM kept, Lock cleared."""
        self.advance_to(t_us)
        eeprom = bytes(self.table[:ax12.EEPROM_END])
        t = self._present()
        pos = t[36] | (t[37] << 8)
        self.table[:] = ax12.defaults(self.edition, pos)
        self.table[:ax12.EEPROM_END] = eeprom
        self.table[ax12.TORQUE_LIMIT] = eeprom[ax12.MAX_TORQUE]
        self.table[ax12.TORQUE_LIMIT + 1] = eeprom[ax12.MAX_TORQUE + 1]
        self.health.rearm()
        self.alarm_led = False
        self._registered = None
        self._command()
        self._present_stale = True

    # --- instructions --------------------------------------------------------------
    def checksum_error(self, code: int, t_us: int) -> bytes | None:
        """A packet addressed to this servo arrived with a bad checksum: answer bit 4."""
        self.advance_to(t_us)
        if self._deaf(t_us):
            return None
        return self._answer(code, dxl.ERR_CHECKSUM)

    def _answer(self, code: int, error: int) -> bytes | None:
        """The status, as the Status Return Level answers ``code``."""
        return self._calls.answer(self._table_at, self.health.at, code, error)

    def handle(self, code: int, params: bytes, broadcast: bool, t_us: int) -> bytes | None:
        """Execute one instruction at t_us; return the status packet, or None (no reply)."""
        if not self._take(t_us):
            return None
        if code == dxl.SYNC_WRITE:   # every cycle, to every servo: tested first
            self._sync_write(params)
            return None
        if code == dxl.READ and len(params) == 2:
            return self._read(params[0], params[1], broadcast)
        error = 0
        if code == dxl.READ:
            error = dxl.ERR_INSTRUCTION
        elif code == dxl.WRITE or code == dxl.REG_WRITE:
            if len(params) < 2:
                error = dxl.ERR_INSTRUCTION
            else:
                a = params[0]
                d = bytes(params[1:])
                error = self.check_write(a, d)
                if not error & dxl.ERR_RANGE:
                    self._write_or_register(code == dxl.WRITE, a, d)
        elif code == dxl.ACTION:
            registered = self._take_registered()
            if registered is None:
                error = dxl.ERR_INSTRUCTION
            else:
                self._apply_write(*registered)
        elif code == dxl.FACTORY_RESET:
            reply = None if broadcast else self._answer(code, 0)
            self._factory_reset()
            return reply
        elif code != dxl.PING:
            error = dxl.ERR_INSTRUCTION
        alarms = error | self.state_errors()  # a limit just written may already be exceeded
        if alarms:
            self._alarm(alarms)
        if broadcast:
            return None
        return self._answer(code, error)

    def _read(self, address: int, length: int, broadcast: bool) -> bytes | None:
        """The data (Present registers up to date), the alarms and the status."""
        at = (self._at, self.health.at, self._table_at, address, length, broadcast)
        stale = self._present_stale and self.reading is None   # the rule refreshes them
        calls = self._calls
        code = calls.read(*at, self.actuator.state() if stale else None)
        if code & READ_REFRESH:   # a Present Position fault reads its own way
            self._refresh_present()
            code = calls.read(*at, None)
        if code & READ_COMMAND:
            self._command()
        return calls.status(code)

    def _sync_write(self, params: bytes) -> None:
        """Its ID's first entry, checked (refused on a Range error: no status) and applied."""
        if servo_rules.sync_write(self._at, self.health.at, self._table_at,
                                  self.edition == ax12.EDITION_ORIGINAL, params) & APPLY_COMMAND:
            self._command()

    def check_write(self, address: int, data: bytes) -> int:
        """Error bits a WRITE of ``data`` at ``address`` earns; Range means it is refused.

        Refused (our choice of the Range bit where the manuals say only "cannot be
        written"): past the table, read-only or reserved cells, values outside a field's
        range, EEPROM while locked (original manual: everything but 24-35 while locked).
        Angle limit: a goal outside CW..CCW is stored, the horn stops at the limit.
        """
        return servo_rules.check_write(self.edition == ax12.EDITION_ORIGINAL, self._table_at,
                                       address, data)

    def _apply_write(self, address: int, data: bytes) -> None:
        """A checked write (``check_write``) and its effects: EEPROM busy, the line
        re-indexed, the overload re-armed, the drive commanded."""
        if servo_rules.apply(self._at, self.health.at, self._table_at, address, bytes(data),
                             len(data)) & APPLY_COMMAND:
            self._command()

    def _factory_reset(self) -> None:
        t = self._present()
        pos = t[36] | (t[37] << 8)
        self.table[:] = ax12.defaults(self.edition, pos)
        self.deaf_until_us = self.t_us + self.eeprom_busy_us
        self._registered = None
        self.health.overload = False
        self.alarm_led = False
        self.address_changed = True
        self._command()
        self._present_stale = True
