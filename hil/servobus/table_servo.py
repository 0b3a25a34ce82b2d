"""What the emulated AX-12 (hil/servobus/ax12_servo.py) and XL430 (hil/servobus/xseries_servo.py) share.

Both keep their state in a control table laid out by a protocol module (``layout``:
protocol/dynamixel/ax12.py or xl430.py, which name the same registers alike), turn the horn through
an ``Actuator``, finish an EEPROM write before they take the next packet and go deaf while
they reboot. From those this base reads the identity, takes an instruction (late while an
EEPROM write finishes; not at all while deaf), keeps a REG_WRITE for ACTION and gives the
recorder its state; each servo executes its own instruction set.

An EEPROM write is not a deaf time (sources in docs/servo-bus.md): ROBOTIS's own
advice for wheel mode is two WRITEs back to back, each waiting for its status, and users
confirm it on AX-12 and X-series servos. The servo's UART keeps receiving while the write
finishes; the packet is executed when it is done and its Return Delay counts from then.
"""
from __future__ import annotations

from types import ModuleType
from typing import Any

from hexhil.hil.servobus.drive import Actuator, is_moving
from hexhil.hil.servobus.health import ServoHealth


class TableServo:
    """A servo on the bus whose state is its control table ``table``."""

    layout: ModuleType              # the control table's module (ID, BAUD_RATE, ...)
    table: bytearray
    actuator: Actuator
    health: ServoHealth
    busy_until_us: int              # an EEPROM write under way until then: packets wait
    deaf_until_us: int              # rebooting until then: packets are lost
    ignored: int                    # packets that arrived while deaf
    held: int                       # packets that waited for an EEPROM write
    held_us: int                    # how long the packet last taken waited
    instructions: int               # packets executed
    reading: Any = None             # a Present Position fault (hil/servobus/faults.py), or None
    _registered: tuple[int, bytes] | None

    def advance_to(self, t_us: int) -> None:
        raise NotImplementedError

    def state_errors(self) -> int:
        raise NotImplementedError

    def _apply_write(self, address: int, data: bytes) -> None:
        raise NotImplementedError

    def _refresh_present(self) -> None:
        raise NotImplementedError

    # --- identity ----------------------------------------------------------------------
    @property
    def id(self) -> int:
        return self.table[self.layout.ID]

    @property
    def baud_bps(self) -> int:
        return self.layout.baud_to_bps(self.table[self.layout.BAUD_RATE])

    @property
    def return_delay_us(self) -> int:
        """From the end of the packet to the status: Return Delay Time after the servo took
        it (later when it waited for an EEPROM write)."""
        return self.layout.return_delay_us(self.table[self.layout.RETURN_DELAY_TIME]) + self.held_us

    @property
    def torque_on(self) -> bool:
        return bool(self.table[self.layout.TORQUE_ENABLE])

    @property
    def moving(self) -> bool:
        """The Moving flag without refreshing the rest of the table."""
        return is_moving(self.actuator.state()[1])

    def state_row(self) -> tuple:
        """The servo's state in SI units, as the recorder logs it on ``/servos``: the
        fields of ``hil.seams.SERVO_STATE_FIELDS`` in order, a plain tuple (what the
        recorder holds and pickles at the least cost)."""
        pos, vel, load = self.actuator.state()
        health, table, layout = self.health, self.table, self.layout
        return (table[layout.ID], pos, vel, load, health.temperature_c, health.supply_v,
                table[layout.TORQUE_ENABLE] != 0, is_moving(vel), self.state_errors())

    def set_hot_spot(self, temperature_c: float | None, t_us: int) -> None:
        self.advance_to(t_us)
        self.health.hot_spot_c = temperature_c

    # --- injected faults (hil/servobus/faults.py) ---------------------------------------
    def set_reading(self, reading: Any, t_us: int) -> None:
        """Present Position read through ``reading.apply(units)`` (stuck, noisy), or true."""
        self.advance_to(t_us)
        self.reading = reading
        self._refresh_present()   # a stuck reading keeps what it reads now

    def set_id(self, dev_id: int, t_us: int) -> None:
        """The ID register changed behind the master's back (a spare with another ID)."""
        self.advance_to(t_us)
        self.table[self.layout.ID] = dev_id

    def _position_read(self, units: int) -> int:
        return units if self.reading is None else self.reading.apply(units)

    # --- instructions ------------------------------------------------------------------
    def _deaf(self, t_us: int) -> bool:
        self.held_us = 0
        if t_us < self.deaf_until_us:
            self.ignored += 1
            return True
        return False

    def _take(self, t_us: int) -> bool:
        """Catch up to ``t_us`` (or the end of an EEPROM write under way) and take an
        instruction: False when deaf (ignored)."""
        hold = max(0, self.busy_until_us - t_us)
        self.advance_to(t_us + hold)
        if self._deaf(t_us + hold):
            return False
        self.held_us = hold
        self.held += hold > 0
        self.instructions += 1
        return True

    def _write_or_register(self, write: bool, address: int, data: bytes) -> None:
        """WRITE applies ``data`` now; REG_WRITE keeps it for ACTION (Registered set)."""
        if write:
            self._apply_write(address, data)
        else:
            self._registered = (address, data)
            self.table[self.layout.REGISTERED] = 1

    def _take_registered(self) -> tuple[int, bytes] | None:
        """ACTION: the registered write, forgotten now; None when nothing was registered."""
        registered = self._registered
        if registered is not None:
            self._registered = None
            self.table[self.layout.REGISTERED] = 0
        return registered
