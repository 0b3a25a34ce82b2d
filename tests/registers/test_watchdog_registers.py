"""IWDG and WWDG (hil/mcu/devices/iwdg.py, wwdg.py) through the bus: reset values, the key
protocol, PVU/RVU timing, and a timeout resetting the MCU as SYSRESETREQ does, named and
counted, with RCC CSR's reset flag set."""
import pytest

from registers.bus import Bus

IWDG, WWDG = 0x40003000, 0x40002C00
KR, PR, RLR, SR = (IWDG + o for o in (0x00, 0x04, 0x08, 0x0C))
RCC_CSR = 0x40023874
IWDGRSTF, WWDGRSTF = 1 << 29, 1 << 30


@pytest.fixture
def bus():
    return Bus()


def test_iwdg_reset_values(bus):
    assert [bus.read(a) for a in (KR, PR, RLR, SR)] == [0, 0, 0xFFF, 0]


def test_iwdg_prescaler_and_reload_need_the_unlock_key(bus):
    bus.write(PR, 3)
    bus.write(RLR, 100)
    assert (bus.read(PR), bus.read(RLR)) == (0, 0xFFF)
    bus.write(KR, 0x5555)
    bus.write(PR, 3)
    bus.write(RLR, 100)
    assert (bus.read(PR), bus.read(RLR)) == (3, 100)


def test_iwdg_update_flags_clear_after_five_lsi_periods(bus):
    bus.write(KR, 0x5555)
    bus.write(PR, 2)
    assert bus.read(SR) == 1                   # PVU
    bus.write(RLR, 10)
    assert bus.read(SR) == 3                   # PVU and RVU
    bus.advance(140e-6)                        # 5 periods of 32 kHz: 156 us
    assert bus.read(SR) == 3
    bus.advance(30e-6)
    assert bus.read(SR) == 0


def test_iwdg_timeout_resets_the_mcu_named_and_counted(bus):
    bus.write(KR, 0x5555)
    bus.write(RLR, 249)                        # PR 0: /4, 125 us a count: 31.25 ms
    bus.write(KR, 0xAAAA)
    bus.write(KR, 0xCCCC)                      # starts from 0xFFF: 511.875 ms
    bus.advance(0.5)
    assert bus.board.resets == 0
    bus.write(KR, 0xAAAA)                      # reloaded from RLR
    bus.advance(0.031)
    assert bus.board.resets == 0
    assert bus.read(RCC_CSR) & IWDGRSTF == 0
    bus.advance(0.0005)
    assert bus.board.resets == 1 and bus.board.reset_causes == {"IWDG": 1}
    assert bus.read(RCC_CSR) & IWDGRSTF
    assert bus.read(RLR) == 0xFFF              # the IWDG too is at reset, stopped
    bus.advance(1.0)
    assert bus.board.resets == 1
    bus.write(RCC_CSR, 1 << 24)                # RMVF clears the reset flags
    assert bus.read(RCC_CSR) & 0xFE000000 == 0


def test_wwdg_reset_values(bus):
    bus.enable("WWDG")
    assert [bus.read(WWDG + o) for o in (0, 4, 8)] == [0x7F, 0x7F, 0]


def test_wwdg_counts_down_and_resets_when_t6_falls(bus):
    bus.enable("WWDG")
    bus.write(WWDG + 0x04, 0x7F | 1 << 9)      # window 0x7F, WDGTB 0, EWI
    bus.write(WWDG + 0x00, 0x80 | 0x50)        # WDGA, T = 0x50
    tick = 4096 / 16e6                         # PCLK1 16 MHz at reset
    bus.advance(5.5 * tick)
    assert bus.read(WWDG) & 0x7F == 0x50 - 5
    bus.advance(11 * tick)                     # T = 0x40: the early wakeup
    assert bus.read(WWDG + 0x08) == 1 and bus.pending(0)
    bus.write(WWDG + 0x08, 0)                  # EWIF is rc_w0
    assert bus.read(WWDG + 0x08) == 0
    assert bus.board.resets == 0
    bus.advance(tick)
    assert bus.board.reset_causes == {"WWDG": 1}
    assert bus.read(RCC_CSR) & WWDGRSTF


def test_wwdg_refreshed_above_the_window_resets(bus):
    bus.enable("WWDG")
    bus.write(WWDG + 0x04, 0x60)               # window 0x60
    bus.write(WWDG + 0x00, 0xFF)               # WDGA, T = 0x7F
    bus.write(WWDG + 0x00, 0xFF)               # the counter (0x7F) is above the window
    assert bus.board.reset_causes == {"WWDG": 1}


def test_wwdg_activation_bit_is_set_only(bus):
    bus.enable("WWDG")
    bus.write(WWDG + 0x00, 0xFF)
    bus.write(WWDG + 0x00, 0x7F)               # WDGA written 0: still set (and refreshed)
    assert bus.read(WWDG) & 0x80
