"""Supply voltage, temperature and overload of one emulated AX-12A: the state behind the
Input Voltage, Overheating and Overload error bits (``ServoHealth.errors``).

The manuals give the limits (Min/Max Voltage Limit, Temperature Limit, Torque Limit) but
no thermal data and no overload timing; the models below are our choices, listed in
docs/servo-bus.md. The servo (hil/servobus/ax12_servo.py) acts on the bits: Alarm LED and shutdown.
"""
from __future__ import annotations

import ctypes
import math

from hexhil.hil.servobus.servo_layout import HEALTH
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl

# Thermal model (our choice; the manuals give no thermal data): first order,
# dT/dt = (ambient + HEAT_AT_FULL_LOAD_C * load^2 - T) / THERMAL_TAU_S.
AMBIENT_C = 32.0               # the manuals' power-on Present Temperature
HEAT_AT_FULL_LOAD_C = 60.0     # steady rise above ambient at 100 % load
THERMAL_TAU_S = 60.0
OVERHEAT_TAU_S = 1.0           # time constant towards an injected hot-spot temperature
# Overload (our choice): load saturated at the torque limit for this long sets the bit.
OVERLOAD_TIME_US = 1_000_000
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
        super().__init__()
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
        self.overload = False
        self.saturated_us = 0

    def advance(self, dt_us: int, load_frac: float, torque_limit: int) -> None:
        """``dt_us`` at ``load_frac`` against ``torque_limit`` (raw units; 0 with torque off)."""
        if torque_limit and abs(load_frac) * 1023.0 >= torque_limit * self.supply_frac - 0.5:
            self.saturated_us += dt_us
            if self.saturated_us >= OVERLOAD_TIME_US:
                self.overload = True
        else:
            self.saturated_us = 0
        if self._hot:
            target, tau = self._hot_spot_c, OVERHEAT_TAU_S
        else:
            target, tau = AMBIENT_C + HEAT_AT_FULL_LOAD_C * load_frac * load_frac, THERMAL_TAU_S
        if target != self.temperature_c:
            k = math.exp(-dt_us * 1e-6 / tau)
            self._set_temperature_c(target + (self.temperature_c - target) * k)

    def errors(self, table: bytearray) -> int:
        """Error bits for the table's limits: Input Voltage, Overheating, Overload."""
        e = 0
        v = self.voltage_units
        if v < table[ax12.MIN_VOLTAGE_LIMIT] or v > table[ax12.MAX_VOLTAGE_LIMIT]:
            e |= dxl.ERR_INPUT_VOLTAGE
        if self.temperature_units > table[ax12.TEMPERATURE_LIMIT]:
            e |= dxl.ERR_OVERHEATING
        if self.overload:
            e |= dxl.ERR_OVERLOAD
        return e
