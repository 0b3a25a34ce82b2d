"""ADC1 and the ADC common registers (RM0383 11.12) as a register file: no conversion is
modelled (EOC never comes), the HAL's configuration reads back.
"""
from __future__ import annotations

from hil.mcu.registers import Description, reg


def _sample_times(first: int, count: int) -> str:
    return " ".join(f"SMP{first + i}:{3 * i}-{3 * i + 2}:rw" for i in range(count))


def _sequence(first: int, count: int) -> str:
    return " ".join(f"SQ{first + i}:{5 * i}-{5 * i + 4}:rw" for i in range(count))


ADC1 = Description("ADC1", (
    reg("SR", 0x00, 0, "AWD:0:rc_w0 EOC:1:rc_w0 JEOC:2:rc_w0 JSTRT:3:rc_w0 STRT:4:rc_w0 "
        "OVR:5:rc_w0"),
    reg("CR1", 0x04, 0, "AWDCH:0-4:rw EOCIE:5:rw AWDIE:6:rw JEOCIE:7:rw SCAN:8:rw "
        "AWDSGL:9:rw JAUTO:10:rw DISCEN:11:rw JDISCEN:12:rw DISCNUM:13-15:rw JAWDEN:22:rw "
        "AWDEN:23:rw RES:24-25:rw OVRIE:26:rw"),
    reg("CR2", 0x08, 0, "ADON:0:rw CONT:1:rw DMA:8:rw DDS:9:rw EOCS:10:rw ALIGN:11:rw "
        "JEXTSEL:16-19:rw JEXTEN:20-21:rw JSWSTART:22:rw EXTSEL:24-27:rw EXTEN:28-29:rw "
        "SWSTART:30:rw"),
    reg("SMPR1", 0x0C, 0, _sample_times(10, 9)),
    reg("SMPR2", 0x10, 0, _sample_times(0, 10)),
    *(reg(f"JOFR{i + 1}", 0x14 + 4 * i, 0, f"JOFFSET{i + 1}:0-11:rw") for i in range(4)),
    reg("HTR", 0x24, 0x0FFF, "HT:0-11:rw"),
    reg("LTR", 0x28, 0, "LT:0-11:rw"),
    reg("SQR1", 0x2C, 0, _sequence(13, 4) + " L:20-23:rw"),
    reg("SQR2", 0x30, 0, _sequence(7, 6)),
    reg("SQR3", 0x34, 0, _sequence(1, 6)),
    reg("JSQR", 0x38, 0, " ".join(f"JSQ{i + 1}:{5 * i}-{5 * i + 4}:rw" for i in range(4))
        + " JL:20-21:rw"),
    *(reg(f"JDR{i + 1}", 0x3C + 4 * i, 0, "JDATA:0-15:r") for i in range(4)),
    reg("DR", 0x4C, 0, "DATA:0-15:r"),
    reg("CSR", 0x300, 0, "AWD1:0:r EOC1:1:r JEOC1:2:r JSTRT1:3:r STRT1:4:r OVR1:5:r"),
    reg("CCR", 0x304, 0, "ADCPRE:16-17:rw VBATE:22:rw TSVREFE:23:rw"),
))
