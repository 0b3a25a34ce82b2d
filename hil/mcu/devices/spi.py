"""SPI1-5 and the I2S2ext/I2S3ext blocks (RM0383 20.5) as a register file: no transfer is
modelled (TXE reads set, nothing is received), the HAL's configuration reads back.
"""
from __future__ import annotations

from hexhil.hil.mcu.registers import Description, reg

SPI = Description("SPI", (
    reg("CR1", 0x00, 0, "CPHA:0:rw CPOL:1:rw MSTR:2:rw BR:3-5:rw SPE:6:rw LSBFIRST:7:rw "
        "SSI:8:rw SSM:9:rw RXONLY:10:rw DFF:11:rw CRCNEXT:12:rw CRCEN:13:rw BIDIOE:14:rw "
        "BIDIMODE:15:rw"),
    reg("CR2", 0x04, 0, "RXDMAEN:0:rw TXDMAEN:1:rw SSOE:2:rw FRF:4:rw ERRIE:5:rw "
        "RXNEIE:6:rw TXEIE:7:rw"),
    reg("SR", 0x08, 0x0002, "RXNE:0:r TXE:1:r CHSIDE:2:r UDR:3:r CRCERR:4:rc_w0 MODF:5:r "
        "OVR:6:r BSY:7:r FRE:8:r"),
    reg("DR", 0x0C, 0, "DR:0-15:rw"),
    reg("CRCPR", 0x10, 0x0007, "CRCPOLY:0-15:rw"),
    reg("RXCRCR", 0x14, 0, "RXCRC:0-15:r"),
    reg("TXCRCR", 0x18, 0, "TXCRC:0-15:r"),
    reg("I2SCFGR", 0x1C, 0, "CHLEN:0:rw DATLEN:1-2:rw CKPOL:3:rw I2SSTD:4-5:rw "
        "PCMSYNC:7:rw I2SCFG:8-9:rw I2SE:10:rw I2SMOD:11:rw"),
    reg("I2SPR", 0x20, 0x0002, "I2SDIV:0-7:rw ODD:8:rw MCKOE:9:rw"),
))
