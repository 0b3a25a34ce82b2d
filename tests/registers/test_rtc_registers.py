"""RTC as a register file through the bus (hil/mcu/devices/rtc.py): RM0383's reset values,
rc_w0 flags, read-only bits kept, write-only keys reading 0, the backup registers, and
the accesses named in the log as RTC.REGISTER and RTC+0xOFF."""
import logging

import pytest

from registers.bus import Bus

RTC = 0x40002800
TR, DR, CR, ISR, PRER, WUTR, WPR, SSR, BKP0R = 0x00, 0x04, 0x08, 0x0C, 0x10, 0x14, 0x24, \
    0x28, 0x50


@pytest.fixture
def bus():
    return Bus()


def test_reset_values(bus):
    values = {o: bus.read(RTC + o) for o in (TR, DR, CR, ISR, PRER, WUTR, SSR, BKP0R)}
    assert values == {TR: 0, DR: 0x2101, CR: 0, ISR: 0x07, PRER: 0x007F00FF, WUTR: 0xFFFF,
                      SSR: 0, BKP0R: 0}


def test_isr_init_is_rw_its_ready_flags_read_only_rsf_rc_w0(bus):
    bus.write(RTC + ISR, 0xFFFFFFFF)
    assert bus.read(RTC + ISR) == 0x07 | 1 << 7        # INIT set; RSF, INITF... not
    bus.board.space._live[(RTC - 0x40000000) >> 10].set_bits("ISR", 1 << 5)   # RSF
    bus.write(RTC + ISR, 0xFFFFFFFF & ~(1 << 5))      # RSF cleared by its 0
    assert bus.read(RTC + ISR) == 0x07 | 1 << 7


def test_write_protection_key_reads_0_and_the_backup_registers_keep_words(bus):
    bus.write(RTC + WPR, 0xCA)
    assert bus.read(RTC + WPR) == 0
    for i in range(20):
        bus.write(RTC + BKP0R + 4 * i, 0x1000 + i)
    assert [bus.read(RTC + BKP0R + 4 * i) for i in range(20)] == [0x1000 + i for i in range(20)]
    bus.write(RTC + SSR, 0x1234)                       # read only
    assert bus.read(RTC + SSR) == 0


def test_accesses_are_named_once_a_run(bus, caplog):
    with caplog.at_level(logging.WARNING, logger="hil.mcu.registers"):
        bus.read(RTC + ISR)
        bus.write(RTC + ISR, 0)
        bus.read(RTC + 0x4C)                           # between ALRMBSSR and BKP0R
        bus.write(0xE000ED0C, 0x05FA0004)              # SYSRESETREQ: the same run
        bus.read(RTC + ISR)
    names = [r.getMessage().split()[2].rstrip(",") for r in caplog.records]
    assert names == ["RTC.ISR", "RTC+0x04C"]
    assert bus.board.resets == 1


def test_a_half_word_write_reaches_its_half(bus):
    bus.write(RTC + WUTR, 0x1234, size=2)
    assert bus.read(RTC + WUTR) == 0x1234
