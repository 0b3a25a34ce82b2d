"""What the emulated AX-12 (hil/servobus/ax12_servo.py) and XL430 (hil/servobus/xseries_servo.py) share.

Both keep their state in a control table laid out by a protocol module (``layout``:
protocol/dynamixel/ax12.py or xl430.py, which name the same registers alike), turn the horn through
an ``Actuator`` and go deaf for a while after an EEPROM write. From those this base reads
the identity, takes an instruction (or ignores it while deaf), keeps a REG_WRITE for
ACTION and gives the recorder its snapshot; each servo executes its own instruction set.
"""
from __future__ import annotations

from types import ModuleType
from typing import Any

from hil.servobus.drive import Actuator, is_moving
from hil.servobus.health import ServoHealth


class TableServo:
    """A servo on the bus whose state is its control table ``table``."""

    layout: ModuleType              # the control table's module (ID, BAUD_RATE, ...)
    table: bytearray
    actuator: Actuator
    health: ServoHealth
    busy_until_us: int              # deaf after an EEPROM write until then
    ignored: int                    # packets that arrived while deaf
    instructions: int               # packets executed
    _registered: tuple[int, bytes] | None

    def advance_to(self, t_us: int) -> None:
        raise NotImplementedError

    def state_errors(self) -> int:
        raise NotImplementedError

    def _apply_write(self, address: int, data: bytes) -> None:
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
        return self.layout.return_delay_us(self.table[self.layout.RETURN_DELAY_TIME])

    @property
    def torque_on(self) -> bool:
        return bool(self.table[self.layout.TORQUE_ENABLE])

    @property
    def moving(self) -> bool:
        """The Moving flag without refreshing the rest of the table."""
        return is_moving(self.actuator.state()[1])

    def snapshot(self) -> dict[str, Any]:
        """The servo's state in SI units, as the recorder logs it on ``/servos``."""
        pos, vel, load = self.actuator.state()
        return {"id": self.id, "position_rad": pos, "velocity_rad_s": vel, "load_frac": load,
                "temperature_c": self.health.temperature_c, "voltage_v": self.health.supply_v,
                "torque_enabled": self.torque_on, "moving": is_moving(vel),
                "error": self.state_errors()}

    def set_hot_spot(self, temperature_c: float | None, t_us: int) -> None:
        self.advance_to(t_us)
        self.health.hot_spot_c = temperature_c

    # --- instructions ------------------------------------------------------------------
    def _deaf(self, t_us: int) -> bool:
        if t_us < self.busy_until_us:
            self.ignored += 1
            return True
        return False

    def _take(self, t_us: int) -> bool:
        """Catch up to ``t_us`` and take an instruction: False when deaf (ignored)."""
        self.advance_to(t_us)
        if self._deaf(t_us):
            return False
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
