"""Supply voltage, temperature and overload of one emulated AX-12A: the state behind the
Input Voltage, Overheating and Overload error bits (``ServoHealth.errors``).

The manuals give the limits (Min/Max Voltage Limit, Temperature Limit, Torque Limit) but
no thermal data and no overload timing; the models are our choices, listed in
docs/servo-bus.md, their parameters in servo_layout.py. The rule is compiled once
(servo_rules.py): the servos the compiled SYNC_WRITE serves and those served here step it
by the same code. The servo (hil/servobus/ax12_servo.py) acts on the bits: Alarm LED and
shutdown.
"""
from __future__ import annotations

import ctypes

from hexhil.hil.servobus import servo_rules
from hexhil.hil.servobus.servo_layout import AMBIENT_C, HEALTH
from hexhil.protocol.dynamixel import ax12

SUPPLY_V = 12.0                # nominal AX-12A supply


def _unit_byte(n: int) -> int:
    """A Present Voltage/Temperature reading saturates at its byte."""
    return 0 if n < 0 else (255 if n > 255 else n)


class ServoHealth(ctypes.Structure):
    """Supply, temperature and the overload latch, with their control-table units.

    Present Voltage and Present Temperature units are kept beside the SI values: the alarm
    check reads them twice per instruction. A ctypes structure: the compiled SYNC_WRITE
    (hil/servobus/servo_core.c) steps it in place.
    """

    _fields_ = HEALTH   # servo_layout.py: the C code's ``struct health`` too

    def __init__(self) -> None:
        servo_rules.require()
        super().__init__()
        self.at = ctypes.addressof(self)   # what the compiled rules take
        self.set_supply_v(SUPPLY_V)
        self._set_temperature_c(AMBIENT_C)

    @property
    def hot_spot_c(self) -> float | None:
        """The injected overheating target, or None."""
        return self._hot_spot_c if self._hot else None

    @hot_spot_c.setter
    def hot_spot_c(self, celsius: float | None) -> None:
        self._hot = celsius is not None
        self._hot_spot_c = 0.0 if celsius is None else celsius

    def set_supply_v(self, volts: float) -> None:
        """The supply, and ``supply_frac``: its fraction of the rated 12 V, in [0, 1], what
        scales speed and torque (kept, not computed at each of the servo's reads)."""
        self.supply_v = volts
        self.supply_frac = min(1.0, max(0.0, volts / SUPPLY_V))
        self.voltage_units = _unit_byte(ax12.v_to_voltage(volts))

    def _set_temperature_c(self, celsius: float) -> None:
        self.temperature_c = celsius
        self.temperature_units = _unit_byte(int(round(celsius)))

    def rearm(self) -> None:
        """Torque Limit written again (or power back): the overload latch clears."""
        servo_rules.rearm(self.at)

    def advance(self, dt_us: int, load_frac: float, torque_limit: int) -> None:
        """``dt_us`` at ``load_frac`` against ``torque_limit`` (raw units; 0 with torque off)."""
        servo_rules.health_advance(self.at, dt_us, load_frac, torque_limit)

    def errors(self, table_at: int) -> int:
        """Error bits for an AX-12 table's limits (its address, servo_rules.py ``address``):
        Input Voltage, Overheating, Overload."""
        return servo_rules.health_errors(self.at, table_at)
