"""ADC1 and the ADC common registers (RM0383 11): a regular conversion by software start.

SWSTART with ADON converts SQ1 (CONT: again and again): STRT at once, EOC (its interrupt
with EOCIE) after the sampling time of the channel's SMP plus the resolution's cycles of
ADCCLK (PCLK2 / 2, 4, 6 or 8 by CCR ADCPRE); reading DR clears EOC. What is converted,
at VDDA = 3.3 V: VREFINT on channel 17 (1.21 V, with CCR TSVREFE), the temperature sensor
at 25 C on channel 18 (0.76 V, TSVREFE), or VBAT / 4 there (3.3 V, VBATE, which wins), as
the F411 shares the channel; the pins read 0 V (nothing on this board drives them). The
factory calibration words in system memory (VREFIN_CAL, TS_CAL1, TS_CAL2: device_id.py)
agree with these. Not modelled: scan sequences, injected conversions, external triggers,
DMA, the watchdog, overrun.
"""
from __future__ import annotations

from typing import Any

from hexhil.hil.mcu.registers import Description, RegisterFile, reg
from hexhil.hil.mcu.timebase import FS_PER_S

VDDA_V = 3.3
VREFINT_V, TEMP_25C_V, TEMP_SLOPE_V = 1.21, 0.76, 0.0025
SAMPLE_CYCLES = (3, 15, 28, 56, 84, 112, 144, 480)      # SMPx
EOC, STRT, ADON, CONT, SWSTART, EOCIE = 1 << 1, 1 << 4, 1, 1 << 1, 1 << 30, 1 << 5
VBATE, TSVREFE = 1 << 22, 1 << 23


def counts(volts: float) -> int:
    """The 12-bit conversion of ``volts`` against VDDA."""
    return max(0, min(4095, round(volts / VDDA_V * 4095)))


def temperature_v(celsius: float) -> float:
    return TEMP_25C_V + (celsius - 25) * TEMP_SLOPE_V


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


class Adc(RegisterFile):
    def __init__(self, board: Any, row: Any) -> None:
        super().__init__(ADC1.renamed(row.name), board.noted)
        self.board, self.irq = board, row.irq_numbers[0]
        self.done = board.events.timer(self._converted)
        self._result = 0
        self.behave("CR2", write=self._cr2)
        self.behave("DR", read=self._dr)
        self.behave("SR", write=lambda old, new: self._line())
        self.behave("CR1", write=lambda old, new: self._line())
        for name in ("SMPR1", "SMPR2", "SQR3", "CCR"):     # read at each conversion
            self.behave(name, write=lambda old, new: None)
        self.pollable = frozenset(self.by_offset) - {self.offset("DR")}

    def _channel_v(self, channel: int) -> float:
        ccr = self.value("CCR")
        if channel == 17 and ccr & TSVREFE:
            return VREFINT_V
        if channel == 18 and ccr & VBATE:
            return VDDA_V / 4
        if channel == 18 and ccr & TSVREFE:
            return temperature_v(25)
        return 0.0

    def _conversion_fs(self, channel: int) -> int:
        smpr = self.value("SMPR1") if channel >= 10 else self.value("SMPR2")
        smp = smpr >> 3 * (channel % 10) & 7
        bits = 12 - 2 * self.field_value("CR1", "RES")
        adcclk = self.board.rcc.pclk2_hz // (2 * (self.field_value("CCR", "ADCPRE") + 1))
        return (SAMPLE_CYCLES[smp] + bits) * FS_PER_S // adcclk

    def _cr2(self, old: int, new: int) -> None:
        if not new & ADON:
            self.done.clear()
        elif new & SWSTART:
            self.set_bits("SR", STRT)
            self._start()
        self.clear_bits("CR2", SWSTART)         # cleared as the conversion starts

    def _start(self) -> None:
        channel = self.field_value("SQR3", "SQ1")
        value = counts(self._channel_v(channel)) >> 2 * self.field_value("CR1", "RES")
        if self.value("CR2") & 1 << 11:        # ALIGN left
            value = value << (4 + 2 * self.field_value("CR1", "RES")) & 0xFFFF
        self._result = value
        self.done.set(self.board.core.now_fs() + self._conversion_fs(channel))

    def _converted(self, at_fs: int) -> None:
        self.regs[self.offset("DR")] = self._result
        self.set_bits("SR", EOC)
        self._line()
        if self.value("CR2") & CONT and self.value("CR2") & ADON:
            self._start()

    def _dr(self) -> int:
        self.clear_bits("SR", EOC)
        self._line()
        return self.value("DR")

    def _line(self) -> None:
        level = bool(self.value("SR") & EOC and self.value("CR1") & EOCIE)
        self.board.irq_lines(self.irq, self, level)
