"""The peripheral bit-band alias (hil/mcu/bitband.py) onto register-file and hand-written
peripherals: a read gives the bit, a write changes that bit alone through the register's
access rules."""
import pytest

from hexhil.hil.mcu.bitband import alias_of
from registers.bus import Bus

PERIPH, ALIAS = 0x40000000, 0x42000000


def bit(addr, n):
    return alias_of(PERIPH, ALIAS, addr, 0) + 4 * n


@pytest.fixture
def bus():
    return Bus()


def _backup_domain_writable(bus):
    """PWR's clock on and PWR CR DBP set: the RTC takes writes (RM0383 5.1.2)."""
    bus.write(0x40023840, bus.read(0x40023840) | 1 << 28)
    bus.write(0x40007000, bus.read(0x40007000) | 1 << 8)


def test_rtc_backup_register_bits(bus):
    bkp = 0x40002850
    _backup_domain_writable(bus)
    bus.write(bit(bkp, 31), 1)
    bus.write(bit(bkp, 3), 1)
    assert bus.read(bkp) == 0x80000008
    assert bus.read(bit(bkp, 31)) == 1 and bus.read(bit(bkp, 30)) == 0
    bus.write(bit(bkp, 31), 0)
    assert bus.read(bkp) == 8


def test_a_read_only_bit_written_through_the_alias_is_kept(bus):
    isr = 0x4000280C                                   # RTC ISR: INITS (bit 4) read only
    _backup_domain_writable(bus)
    bus.write(0x40002824, 0xCA)                        # WPR's key
    bus.write(0x40002824, 0x53)
    bus.write(bit(isr, 4), 1)
    assert bus.read(isr) == 0x07
    bus.write(bit(isr, 7), 1)                          # INIT (rw)
    assert bus.read(isr) == 0x87


def test_rcc_pll_on_through_its_alias_as_the_hal_does(bus):
    cr = 0x40023800
    assert bit(cr, 24) == 0x42470060                   # __HAL_RCC_PLL_ENABLE's address
    bus.write(bit(cr, 24), 1)
    assert bus.read(cr) >> 24 & 1
    bus.advance(0.0002)
    assert bus.read(bit(cr, 25)) == 1                  # PLLRDY


def test_a_timer_flag_cleared_through_its_alias(bus):
    bus.enable("TIM1")
    sr = 0x40010010
    bus.write(0x40010014, 1)                           # UG: UIF
    assert bus.read(bit(sr, 0)) == 1
    bus.write(bit(sr, 0), 0)                           # rc_w0: the 0 clears it
    assert bus.read(sr) & 1 == 0
