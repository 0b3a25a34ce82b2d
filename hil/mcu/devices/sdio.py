"""SDIO (RM0383 21) is on the map, not modelled: each access is named (``SDIO+0xOFF``),
reads 0 and drops writes."""
from __future__ import annotations

from hexhil.hil.mcu.registers import Description

SDIO = Description("SDIO", ())
