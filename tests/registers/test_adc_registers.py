"""ADC1 (hil/mcu/devices/adc.py) through the bus: a software-started conversion of
VREFINT, the temperature sensor and VBAT/4 at VDDA 3.3 V, EOC after the sampling time of
ADCCLK, cleared by reading DR; the calibration words in system memory agree."""
import pytest

from registers.bus import Bus

APB2ENR = 0x40023844
ADC = 0x40012000
SR, CR1, CR2, SMPR1, SQR3, DR, CCR = (ADC + o for o in (0x00, 0x04, 0x08, 0x0C, 0x34, 0x4C,
                                                         0x304))
EOC, STRT = 1 << 1, 1 << 4


def convert(bus, channel, ccr):
    bus.write(CCR, ccr)
    bus.write(SQR3, channel)
    bus.write(CR2, 1)                                # ADON
    bus.write(CR2, 1 | 1 << 30)                      # SWSTART
    started = bus.read(SR)
    bus.advance(60e-6)    # 480 + 12 cycles of 8 MHz (HSI 16 MHz / 2) = 61.5 us: not yet
    early = bus.read(SR)
    bus.advance(5e-6)
    done = bus.read(SR)
    value = bus.read(DR)
    return started, early, done, value, bus.read(SR)


def test_internal_channels_convert_after_the_sampling_time_and_dr_clears_eoc():
    bus = Bus()
    bus.write(APB2ENR, 1 << 8)
    bus.write(SMPR1, 7 << 21 | 7 << 24)              # channels 17, 18: 480 cycles
    started, early, done, vrefint, after = convert(bus, 17, 1 << 23)   # TSVREFE
    assert (started & STRT, early & EOC, done & EOC, after & EOC) == (STRT, 0, EOC, 0)
    assert vrefint == 1502 == bus.read(0x1FFF7A2A, 2)          # 1.21 V; VREFIN_CAL
    temp = convert(bus, 18, 1 << 23)[3]
    cal30, cal110 = bus.read(0x1FFF7A2C, 2), bus.read(0x1FFF7A2E, 2)
    assert temp == 943 and 30 + (temp - cal30) * 80 / (cal110 - cal30) == \
        pytest.approx(25, abs=0.5)               # 25 C by the calibration
    assert convert(bus, 18, 1 << 22 | 1 << 23)[3] == 1024     # VBAT / 4 wins
    assert convert(bus, 3, 1 << 23)[3] == 0                   # a pin nothing drives
