"""One emulated X-series servo (XL430-W250-T, XM430-W350-T, ...): control table, motion,
hardware errors; the Protocol 2.0 instructions are hil/servobus/xseries_instructions.py.

The X-series counterpart of hil/servobus/ax12_servo.py, on the same seams: an ``Actuator``
(hil/servobus/drive.py: kinematic, or a MuJoCo joint of the hexapod world) turns the horn,
``ServoHealth`` (hil/servobus/health.py) holds supply, temperature and the overload latch,
faults (hil/servobus/faults.py) reach it through the same methods. Which model it is, is its
control table (``layout``: protocol/dynamixel/xl430.py, xm430.py, chosen through
protocol/dynamixel/models.py): addresses, limits, units, modes and motor all come from there.

Behaviour follows the ROBOTIS e-manual (X series, Protocol 2.0): operating modes (velocity,
position, extended position, PWM; current and current-based position where the model senses
current), the trapezoid profile (hil/servobus/profile.py), torque enable and the EEPROM lock
(Access error), Return Delay in 2 us units, Status Return Level, Hardware Error Status with
shutdown (torque off until a reboot). Choices the manual leaves open are marked "our choice"
(docs/servo-bus.md).
"""
from __future__ import annotations

import math
from types import ModuleType

from hexhil.hil.servobus.drive import Actuator, KinematicActuator, is_moving
from hexhil.hil.servobus.health import ServoHealth
from hexhil.hil.servobus.profile import Trapezoid
from hexhil.hil.servobus.xseries_instructions import XSeriesInstructions
from hexhil.protocol.dynamixel import v2 as dx2
from hexhil.protocol.dynamixel import xl430


class XSeriesServo(XSeriesInstructions):
    """One X-series servo on a Protocol 2.0 bus; ``handle`` executes an instruction and
    returns the reply (xseries_instructions.py)."""
    def __init__(self, dev_id: int = 1, actuator: Actuator | None = None,
                 position: int | None = None, t_us: int = 0,
                 eeprom_busy_us: int | None = None, layout: ModuleType = xl430) -> None:
        if not 0 <= dev_id <= dx2.MAX_ID:
            raise ValueError(f"servo id {dev_id} outside 0-{dx2.MAX_ID}")
        self.layout = xl = layout
        position = xl.POSITION_CENTRE if position is None else position
        self.no_load_rad_s = xl.NO_LOAD_RPM * 2.0 * math.pi / 60.0   # at the rated supply
        self.table = xl.defaults(position)
        self.table[xl.ID] = dev_id
        self.actuator: Actuator = actuator if actuator is not None else \
            KinematicActuator(xl.position_to_rad(position), t_us)
        self.t_us = t_us
        self.t0_us = t_us                      # power-on, for the Realtime Tick
        self.health = ServoHealth()
        self.eeprom_busy_us = xl.EEPROM_BUSY_US if eeprom_busy_us is None else eeprom_busy_us
        self.busy_until_us = 0                 # an EEPROM write under way until then
        self.deaf_until_us = 0                 # rebooting until then
        self.ignored = 0
        self.held = self.held_us = 0           # packets that waited for an EEPROM write
        self.instructions = 0
        self.address_changed = False
        self.alarm_led = False
        self.turn_offset = 0                   # pulses taken off by CLEAR (multi-turn)
        self._registered: tuple[int, bytes] | None = None
        self._backup: bytes | None = None
        self._profile: Trapezoid | None = None
        self._command()

    @property
    def model(self) -> str:
        return self.layout.MODEL_NAME

    def _get(self, name: str) -> int:
        xl = self.layout
        f = xl.BY_NAME[name]
        return xl.get(self.table, f[0], f[2], f[7])

    def value(self, name: str) -> int:
        """A control-table value by field name (tests, recorder), present values fresh."""
        self._refresh_present()
        return self._get(name)

    @property
    def supply_frac(self) -> float:
        xl = self.layout
        return min(1.0, max(0.0, self.health.supply_v / xl.RATED_SUPPLY_V))

    # --- time, motion, hardware errors --------------------------------------------------
    def advance_to(self, t_us: int) -> None:
        xl = self.layout
        dt_us = t_us - self.t_us
        if dt_us <= 0:
            return
        self.t_us = t_us
        if self._profile is not None and self.torque_on:
            p, _ = self._profile.at(t_us)
            self.actuator.command(p, self.no_load_rad_s * self.supply_frac, self._torque_frac(),
                                  True, self._compliance())
        self.actuator.advance_to(t_us)
        limit = self.table[xl.PWM_LIMIT] | (self.table[xl.PWM_LIMIT + 1] << 8)
        self.health.advance(dt_us, self.actuator.state()[2],
                            (limit * 1023) // xl.PWM_MAX if self.torque_on else 0)
        self._hardware_check()

    def _hardware_check(self) -> None:
        """Latch Hardware Error Status; errors in Shutdown turn the torque off."""
        xl = self.layout
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
        return bool(self.table[self.layout.HARDWARE_ERROR_STATUS]
                    & self.table[self.layout.SHUTDOWN])

    def _present_pulses(self, angle_rad: float) -> int:
        return self.layout.rad_to_position(angle_rad) - self.turn_offset

    def _refresh_present(self) -> None:
        xl = self.layout
        pos, vel, load = self.actuator.state()
        t = self.table
        traj_p, traj_v = (self._profile.at(self.t_us) if self._profile is not None
                          else (pos, vel))
        xl.put(t, xl.PRESENT_POSITION, 4, self._position_read(self._present_pulses(pos)))
        xl.put(t, xl.PRESENT_VELOCITY, 4, xl.rad_s_to_velocity(vel))
        xl.put(t, xl.PRESENT_LOAD, 2, xl.fraction_to_load(load))
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
        return self.table[self.layout.HARDWARE_ERROR_STATUS]

    # --- the drive ----------------------------------------------------------------------
    def _torque_frac(self) -> float:
        xl = self.layout
        t = self.table
        return (t[xl.PWM_LIMIT] | (t[xl.PWM_LIMIT + 1] << 8)) / xl.PWM_MAX * self.supply_frac

    def _compliance(self) -> tuple[float, float, float, float, float]:
        """The P gain as the drive seam's compliance: duty reaches 100 % at an error of
        PWM_MAX * 128 / KPP pulses (e-manual control block: PWM = KPP / 128 * error), given
        in AX-12 position units (0.29 deg) as the seam takes them."""
        xl = self.layout
        kpp = max(1, self._get("position_p_gain"))
        slope_units = xl.PWM_MAX * 128.0 / kpp * xl.RAD_PER_PULSE / math.radians(300.0 / 1023)
        return (0.0, 0.0, slope_units, slope_units, 0.0)

    def _current_frac(self, mode: int) -> float | None:
        """Goal Current over the stall current in a current-based mode (a model with a
        current sensor, ``CURRENT_MODES``), else None."""
        xl = self.layout
        if mode not in xl.CURRENT_MODES:
            return None
        return self._get("goal_current") * xl.CURRENT_A_PER_UNIT / xl.STALL_CURRENT_A

    def _command(self) -> None:
        """Hand the set-point of the present operating mode to the actuator."""
        xl = self.layout
        t = self.table
        mode = t[xl.OPERATING_MODE]
        no_load = self.no_load_rad_s * self.supply_frac
        torque = self._torque_frac()
        enabled = self.torque_on
        pos = self.actuator.state()[0]
        self._profile = None
        if mode == xl.MODE_VELOCITY:
            v = xl.velocity_to_rad_s(self._get("goal_velocity"))
            goal = math.inf if v > 0 else (-math.inf if v < 0 else pos)
            self.actuator.command(goal, min(abs(v), no_load), torque, enabled, self._compliance())
            return
        current = self._current_frac(mode)
        if current is not None:
            torque = min(torque, abs(current))
            if mode not in xl.POSITION_MODES:   # current control: the current's direction
                goal = math.inf if current > 0 else (-math.inf if current < 0 else pos)
                self.actuator.command(goal, no_load, torque, enabled, self._compliance())
                return
        if mode == xl.MODE_PWM:
            duty = self._get("goal_pwm") / xl.PWM_MAX
            goal = math.inf if duty > 0 else (-math.inf if duty < 0 else pos)
            self.actuator.command(goal, abs(duty) * no_load, min(abs(duty), torque), enabled,
                                  self._compliance())
            return
        goal_p = self._get("goal_position") + self.turn_offset
        if mode in xl.LIMITED_POSITION_MODES:
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
        xl = self.layout
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
