"""The limit-switch sensor node: a Dynamixel Protocol 1.0 device beside the servos.

Like the ROBOTIS AX-S1 sensor module (factory ID 100, same bus and protocol as the AX-12),
it lets any master read the six tibia limit switches (seed 003 Sec. 2.3) over the servo
line, with no GPIO wiring. The ``Bus`` serves it like a servo (``handle``,
``checksum_error``, ``id``, ``baud_bps``, ``return_delay_us``).

Control table (documented in docs/servo-bus.md; R = read-only, RW = read/write):

====  ====================  ====  =======  ==========================================
addr  field                 size  access   value
====  ====================  ====  =======  ==========================================
0     Model Number          2     R        ``MODEL_NUMBER`` (not an AX-S1's 13)
2     Firmware Version      1     R        ``FIRMWARE_VERSION``
3     ID                    1     RW       0-253, default 100
4     Baud Rate             1     RW       0-254 (2 Mbps / (n + 1)), default 1 (1 Mbps)
5     Return Delay Time     1     RW       0-254, 2 us a unit, default 250 (500 us)
16    Status Return Level   1     RW       0-2, default 2
26    Switches              1     R        bit i = leg i pressed (LF, LM, LH, RF, RM, RH)
27    Presses               1     R        rising edges seen by reads, modulo 256
====  ====================  ====  =======  ==========================================

Every other address up to 27 reads 0 and refuses writes. Instructions: PING, READ, WRITE
and SYNC_WRITE; any other gets the Instruction bit. No EEPROM busy time (our choice).
"""
from __future__ import annotations

from typing import Callable

from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl
from hexhil.protocol.sensor_node import DEFAULT_ID, MODEL_NUMBER, PRESSES, SWITCHES
FIRMWARE_VERSION = 1
TABLE_SIZE = 28
MODEL_L, VERSION, ID, BAUD_RATE, RETURN_DELAY, STATUS_RETURN_LEVEL = 0, 2, 3, 4, 5, 16
# address -> (low, high) of each writable byte
WRITABLE = {ID: (0, dxl.MAX_ID), BAUD_RATE: (0, 254), RETURN_DELAY: (0, 254),
            STATUS_RETURN_LEVEL: (0, 2)}


class SensorNode:
    """The switch node; ``levels()`` gives the six switch levels as bits (bit i = leg i)."""

    def __init__(self, levels: Callable[[], int], dev_id: int = DEFAULT_ID,
                 baud_register: int = 1) -> None:
        if not 0 <= dev_id <= dxl.MAX_ID:
            raise ValueError(f"sensor node id {dev_id} outside 0-{dxl.MAX_ID}")
        self.levels = levels
        self.table = bytearray(TABLE_SIZE)
        self.table[MODEL_L] = MODEL_NUMBER & 0xFF
        self.table[MODEL_L + 1] = MODEL_NUMBER >> 8
        self.table[VERSION] = FIRMWARE_VERSION
        self.table[ID] = dev_id
        self.table[BAUD_RATE] = baud_register
        self.table[RETURN_DELAY] = 250
        self.table[STATUS_RETURN_LEVEL] = 2
        self.address_changed = False
        self.instructions = 0

    @property
    def id(self) -> int:
        return self.table[ID]

    @property
    def baud_bps(self) -> int:
        return ax12.baud_to_bps(self.table[BAUD_RATE])

    @property
    def return_delay_us(self) -> int:
        return 2 * self.table[RETURN_DELAY]

    def set_supply_v(self, volts: float, t_us: int) -> None:
        """A supply sag on every device: the node's own regulator rides it out."""

    def power_cycle(self, t_us: int) -> None:
        """Plugged back in: RAM (the presses count) cleared, EEPROM kept."""
        self.table[PRESSES] = 0

    def _sample(self) -> None:
        bits = self.levels() & 0x3F
        rising = bits & ~self.table[SWITCHES]
        self.table[PRESSES] = (self.table[PRESSES] + bin(rising).count("1")) & 0xFF
        self.table[SWITCHES] = bits

    def check_write(self, address: int, data: bytes) -> int:
        """Range bit when any byte is read-only, reserved, past the table or out of range."""
        if address + len(data) > TABLE_SIZE:
            return dxl.ERR_RANGE
        for i, v in enumerate(data):
            lim = WRITABLE.get(address + i)
            if lim is None or not lim[0] <= v <= lim[1]:
                return dxl.ERR_RANGE
        return 0

    def _write(self, address: int, data: bytes) -> int:
        error = self.check_write(address, data)
        if not error:
            self.table[address:address + len(data)] = data
            self.address_changed = address <= BAUD_RATE < address + len(data) \
                or address <= ID < address + len(data)
        return error

    def _answer(self, code: int, error: int, params: bytes = b"") -> bytes | None:
        srl = self.table[STATUS_RETURN_LEVEL]
        if srl >= 2 or code == dxl.PING or (srl == 1 and code == dxl.READ):
            return dxl.status(self.table[ID], error, params)
        return None

    def checksum_error(self, code: int, t_us: int) -> bytes | None:
        return self._answer(code, dxl.ERR_CHECKSUM)

    def handle(self, code: int, params: bytes, broadcast: bool, t_us: int) -> bytes | None:
        """Execute one instruction; return the status packet or None."""
        self.instructions += 1
        error, data = 0, b""
        if code == dxl.READ:
            if len(params) != 2:
                error = dxl.ERR_INSTRUCTION
            elif params[1] == 0 or params[0] + params[1] > TABLE_SIZE:
                error = dxl.ERR_RANGE
            else:
                self._sample()
                data = bytes(self.table[params[0]:params[0] + params[1]])
        elif code == dxl.WRITE:
            error = self._write(params[0], bytes(params[1:])) if len(params) >= 2 \
                else dxl.ERR_INSTRUCTION
        elif code == dxl.SYNC_WRITE:
            self._sync_write(params)
            return None
        elif code != dxl.PING:
            error = dxl.ERR_INSTRUCTION
        return None if broadcast else self._answer(code, error, data)

    def _sync_write(self, params: bytes) -> None:
        if len(params) < 2 or params[1] == 0 or (len(params) - 2) % (params[1] + 1):
            return
        stride = params[1] + 1
        for i in range(2, len(params), stride):
            if params[i] == self.id:
                self._write(params[0], bytes(params[i + 1:i + stride]))
                return
