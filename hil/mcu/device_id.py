"""The F411's system memory where firmware reads who the chip is (RM0383 2.3 and 24):
the 96-bit unique device ID at 0x1FFF_7A10 (``HAL_GetUIDw0..2``, MicroPython's
``machine.unique_id``), the flash size in KB at 0x1FFF_7A22 (``FLASHSIZE_BASE``: 512), the
one-time-programmable area before them (erased: 0xFF), the ADC's factory calibration
words (devices/adc.py), read-only, and DBGMCU's IDCODE
(``HAL_GetDEVID``: 0x431, ``HAL_GetREVID``: 0x1000, revision A). The ID is fixed, the same
every run: a board of its own. The bootloader's code (the rest of system memory) reads 0.
"""
from __future__ import annotations

import ctypes
import struct

from unicorn import UC_PROT_READ, Uc

from hexhil.hil.mcu.devices.adc import VREFINT_V, counts, temperature_v

SYSTEM_MEMORY, SYSTEM_MEMORY_SIZE = 0x1FFF0000, 0x8000     # bootloader, OTP, the ID
OTP, OTP_SIZE = 0x1FFF7800, 0x210
UID = 0x1FFF7A10
UID_WORDS = (0x00470031, 0x4C48580D, 0x31484558)  # wafer X/Y, wafer 13, the lot in ASCII
FLASH_SIZE_KB = 0x1FFF7A22
VREFIN_CAL, TS_CAL1, TS_CAL2 = 0x1FFF7A2A, 0x1FFF7A2C, 0x1FFF7A2E   # at VDDA 3.3 V, 30/110 C
DBGMCU_IDCODE = 0xE0042000
IDCODE = 0x10006431                 # REV_ID 0x1000 (A), DEV_ID 0x431 (STM32F411xC/E)


def system_memory() -> ctypes.Array:
    """The bytes of system memory as the chip reads them."""
    mem = ctypes.create_string_buffer(SYSTEM_MEMORY_SIZE)
    ctypes.memset(ctypes.addressof(mem) + OTP - SYSTEM_MEMORY, 0xFF, OTP_SIZE)
    struct.pack_into("<3I", mem, UID - SYSTEM_MEMORY, *UID_WORDS)
    struct.pack_into("<H", mem, FLASH_SIZE_KB - SYSTEM_MEMORY, 512)
    struct.pack_into("<3H", mem, VREFIN_CAL - SYSTEM_MEMORY, counts(VREFINT_V),
                     counts(temperature_v(30)), counts(temperature_v(110)))
    return mem


def attach(uc: Uc) -> ctypes.Array:
    """System memory mapped read-only into ``uc``; the buffer, kept alive by the caller."""
    mem = system_memory()
    uc.mem_map_ptr(SYSTEM_MEMORY, SYSTEM_MEMORY_SIZE, UC_PROT_READ, mem)
    return mem
