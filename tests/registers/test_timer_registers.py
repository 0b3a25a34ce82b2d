"""TIM1 and TIM9-11 (hil/mcu/peripherals.py BasicTimer on APB2) through the bus: the clock
gate, reset values, the update event at ARR after PSC, their IRQ lines (TIM1_UP_TIM10 25,
TIM1_BRK_TIM9 24, TIM1_TRG_COM_TIM11 26, TIM1_CC 27), compare flags, CCR = 0."""
import pytest

from registers.bus import Bus

BASE = {"TIM1": 0x40010000, "TIM9": 0x40014000, "TIM10": 0x40014400, "TIM11": 0x40014800,
        "TIM2": 0x40000000}
CR1, DIER, SR, EGR, CNT, PSC, ARR, CCR1 = 0x00, 0x0C, 0x10, 0x14, 0x24, 0x28, 0x2C, 0x34
UPDATE_IRQ = {"TIM1": 25, "TIM9": 24, "TIM10": 25, "TIM11": 26}


@pytest.fixture
def bus():
    return Bus()


def _start(bus, name, psc=15, arr=999, dier=1):
    """1 MHz at the reset clock (HSI 16 MHz), an update each ms."""
    t = BASE[name]
    bus.enable(name)
    bus.write(t + PSC, psc)
    bus.write(t + ARR, arr)
    bus.write(t + DIER, dier)
    bus.write(t + CR1, 1)
    return t


def test_a_timer_reads_0_until_its_clock_is_on(bus):
    assert bus.read(BASE["TIM1"] + ARR) == 0
    bus.enable("TIM1")
    assert bus.read(BASE["TIM1"] + ARR) == 0xFFFF


@pytest.mark.parametrize("name", ["TIM1", "TIM9", "TIM10", "TIM11"])
def test_update_at_arr_on_its_irq_line(bus, name):
    t = _start(bus, name)
    bus.advance(0.0009)
    assert bus.read(t + SR) & 1 == 0 and not bus.pending(UPDATE_IRQ[name])
    assert 890 <= bus.read(t + CNT) <= 901
    bus.advance(0.0002)
    assert bus.read(t + SR) & 1 and bus.pending(UPDATE_IRQ[name])
    bus.write(t + SR, ~1 & 0xFFFF)             # UIF is rc_w0
    assert bus.read(t + SR) & 1 == 0


def test_tim1_follows_apb2_not_apb1(bus):
    bus.write(0x40023808, 4 << 10)             # PPRE1 /2: APB1 timers still 16 MHz (x2)
    bus.write(0x40023808, 5 << 13)             # PPRE2 /4: TIM1 at 2 * 4 MHz = 8 MHz
    t = _start(bus, "TIM1", psc=7, arr=999)    # 1 MHz: an update each ms
    bus.advance(0.00099)
    assert bus.read(t + SR) & 1 == 0
    bus.advance(0.00002)
    assert bus.read(t + SR) & 1


def test_tim1_and_tim10_share_their_irq_line(bus):
    t1 = _start(bus, "TIM1")
    t10 = _start(bus, "TIM10", arr=1999)
    bus.advance(0.0011)
    assert bus.pending(25)
    bus.write(0xE000E280, 1 << 25)             # ICPR
    bus.write(t1 + SR, 0)                      # TIM1's flag down: the line falls
    assert not bus.pending(25)
    bus.advance(0.001)                         # TIM10's first update, TIM1's second
    bus.write(0xE000E280, 1 << 25)
    bus.write(t1 + SR, 0)                      # TIM10 still holds the line
    assert bus.read(t10 + SR) & 1 and bus.pending(25)


def test_tim1_compare_flag_and_its_own_irq(bus):
    t = BASE["TIM1"]
    bus.enable("TIM1")
    bus.write(t + CCR1, 400)
    t = _start(bus, "TIM1", dier=1 << 1)       # CC1IE
    bus.advance(0.00039)
    assert bus.read(t + SR) & 2 == 0
    bus.advance(0.00002)
    assert bus.read(t + SR) & 2 and bus.pending(27) and not bus.pending(25)


def test_a_compare_at_ccr_0_matches_at_the_update(bus):
    t = _start(bus, "TIM2", dier=1 << 1)       # CCR1 = 0 from reset
    bus.advance(0.0005)
    assert bus.read(t + SR) & 2 == 0
    bus.advance(0.0006)
    assert bus.read(t + SR) & 3 == 3 and bus.pending(28)
