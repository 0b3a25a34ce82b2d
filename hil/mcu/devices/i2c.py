"""I2C1-3 (RM0383 18.6) as a register file: no bus is modelled (no START condition comes:
SB never sets), the HAL's configuration reads back.
"""
from __future__ import annotations

from hil.mcu.registers import Description, reg

I2C = Description("I2C", (
    reg("CR1", 0x00, 0, "PE:0:rw SMBUS:1:rw SMBTYPE:3:rw ENARP:4:rw ENPEC:5:rw ENGC:6:rw "
        "NOSTRETCH:7:rw START:8:rw STOP:9:rw ACK:10:rw POS:11:rw PEC:12:rw ALERT:13:rw "
        "SWRST:15:rw"),
    reg("CR2", 0x04, 0, "FREQ:0-5:rw ITERREN:8:rw ITEVTEN:9:rw ITBUFEN:10:rw DMAEN:11:rw "
        "LAST:12:rw"),
    reg("OAR1", 0x08, 0, "ADD0:0:rw ADD:1-7:rw ADD8_9:8-9:rw ADDMODE:15:rw"),
    reg("OAR2", 0x0C, 0, "ENDUAL:0:rw ADD2:1-7:rw"),
    reg("DR", 0x10, 0, "DR:0-7:rw"),
    reg("SR1", 0x14, 0, "SB:0:r ADDR:1:r BTF:2:r ADD10:3:r STOPF:4:r RXNE:6:r TXE:7:r "
        "BERR:8:rc_w0 ARLO:9:rc_w0 AF:10:rc_w0 OVR:11:rc_w0 PECERR:12:rc_w0 "
        "TIMEOUT:14:rc_w0 SMBALERT:15:rc_w0"),
    reg("SR2", 0x18, 0, "MSL:0:r BUSY:1:r TRA:2:r GENCALL:4:r SMBDEFAULT:5:r SMBHOST:6:r "
        "DUALF:7:r PEC:8-15:r"),
    reg("CCR", 0x1C, 0, "CCR:0-11:rw DUTY:14:rw F_S:15:rw"),
    reg("TRISE", 0x20, 0x0002, "TRISE:0-5:rw"),
    reg("FLTR", 0x24, 0, "DNF:0-3:rw ANFOFF:4:rw"),
))
