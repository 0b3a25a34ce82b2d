"""Every peripheral of the platform table (hil/mcu/platform.py) answers at its address:
RM0383's reset values of the register files (I2C, SPI, ADC1, CRC, GPIOD/E/H), the clock
gate, CRC-32 on DR and DMA's NDTR counting down as a USART moves the bytes."""
import pytest

from hexhil.hil.mcu import platform
from registers.bus import Bus


@pytest.fixture
def bus():
    return Bus()


@pytest.mark.parametrize("name,offset,reset", [
    ("I2C1", 0x20, 0x0002), ("I2C3", 0x20, 0x0002), ("SPI1", 0x08, 0x0002),
    ("SPI5", 0x10, 0x0007), ("SPI2", 0x20, 0x0002), ("ADC1", 0x24, 0x0FFF),
    ("CRC", 0x00, 0xFFFFFFFF), ("GPIOH", 0x00, 0), ("SDIO", 0x00, 0),
])
def test_reset_value_behind_its_clock_gate(bus, name, offset, reset):
    addr = platform.row(name).base + offset
    if reset:
        assert bus.read(addr) == 0                 # clock off: reads 0
    bus.enable(name)
    assert bus.read(addr) == reset


def test_every_table_peripheral_answers_with_its_clock_on(bus):
    live = {p.name for p in bus.board.space._pages.values()}
    wanted = {r.name for r in platform.PLATFORM if r.kind is platform.Kind.PERIPHERAL
              and r.built is not platform.Built.NONE}
    assert wanted <= live, wanted - live


def test_crc_of_a_word(bus):
    bus.enable("CRC")
    crc = platform.row("CRC").base
    bus.write(crc, 0)
    assert bus.read(crc) == 0xC704DD7B             # CRC-32/MPEG-2 of one zero word
    bus.write(crc + 0x08, 1)                       # RESET
    assert bus.read(crc) == 0xFFFFFFFF
    bus.write(crc + 0x04, 0x1A5)                   # IDR: 8 bits
    assert bus.read(crc + 0x04) == 0xA5


def test_gpiod_output_data_and_bsrr(bus):
    bus.enable("GPIOD")
    d = platform.row("GPIOD").base
    bus.write(d + 0x00, 1 << 24)                   # PD12 output
    bus.write(d + 0x18, 1 << 12)                   # BSRR set
    assert bus.read(d + 0x14) == 1 << 12 and bus.read(d + 0x10) >> 12 & 1


def test_dma_ndtr_counts_down_as_the_usart_takes_the_bytes(bus):
    """USART1 TX by DMA2 stream 7 channel 4: NDTR falls a byte at a time, TCIF at 0."""
    bus.enable("GPIOA")
    bus.enable("USART1")
    bus.enable("DMA2")
    usart, dma = 0x40011000, 0x40026400
    for i, byte in enumerate(b"abcd\n"):
        bus.write(0x20001000 + i, byte, size=1)
    bus.write(usart + 0x08, 139)                   # 115200 baud at 16 MHz
    bus.write(usart + 0x0C, 1 << 13 | 1 << 3)      # UE, TE
    s7 = dma + 0x10 + 0x18 * 7
    bus.write(s7 + 0x08, usart + 0x04)             # PAR: DR
    bus.write(s7 + 0x0C, 0x20001000)               # M0AR
    bus.write(s7 + 0x04, 5)                        # NDTR
    bus.write(s7 + 0x00, 4 << 25 | 1 << 10 | 1 << 6)   # channel 4, MINC, memory to periph
    bus.write(usart + 0x14, 1 << 7)                # DMAT
    bus.write(s7 + 0x00, bus.read(s7) | 1)         # EN
    seen = [bus.read(s7 + 0x04)]
    for _ in range(6):
        bus.advance(87e-6)                         # a byte of 10 bits at 115200 baud
        seen.append(bus.read(s7 + 0x04))
    assert seen[0] < 5 and seen[-1] == 0
    assert all(a - b in (0, 1) for a, b in zip(seen, seen[1:]))
    assert len(set(seen)) >= 4
    assert bus.read(dma + 0x04) >> 27 & 1          # HISR: TCIF7
    assert bus.board.console_tail == ["abcd"]
