"""The platform table (hil/mcu/platform.py): RM0383's regions without overlaps, every
peripheral a CubeMX project for the board may touch, the IRQ numbers system.py's IRQS
gives the hand-written models, the clock gates rcc.py uses, and docs/elf-firmware.md's
table as the generator writes it."""
from hexhil.hil.mcu import platform
from hexhil.hil.mcu.platform import PLATFORM, VECTORS, Built, Kind
from hexhil.hil.mcu.rcc import CLOCK_BITS
from hexhil.hil.mcu.platform import NUM_IRQS
from hexhil.hil.mcu.system import IRQS

CUBEMX = ("RCC PWR FLASH RTC IWDG WWDG TIM1 TIM2 TIM3 TIM4 TIM5 TIM9 TIM10 TIM11 ADC1 I2C1 "
          "I2C2 I2C3 SPI1 SPI2 SPI3 SPI4 SPI5 USART1 USART2 USART6 DMA1 DMA2 EXTI SYSCFG "
          "GPIOA GPIOB GPIOC GPIOD GPIOE GPIOH CRC SCB NVIC SysTick DWT FPU").split()


def test_every_peripheral_a_cubemx_project_may_touch_is_modelled():
    built = {r.name for r in PLATFORM if r.built is not Built.NONE}
    assert set(CUBEMX) <= built, set(CUBEMX) - built


def test_no_two_regions_or_peripherals_overlap():
    for kinds in ({Kind.MEMORY, Kind.ALIAS, Kind.BUS}, {Kind.PERIPHERAL, Kind.CORE}):
        spans = sorted((r.base, r.base + r.size, r.name) for r in PLATFORM if r.kind in kinds)
        for (_, end, a), (start, _, b) in zip(spans, spans[1:]):
            assert end <= start, f"{a} overlaps {b}"


def test_each_peripheral_lies_on_its_bus():
    buses = {r.bus: r for r in PLATFORM if r.kind is Kind.BUS}
    for r in PLATFORM:
        if r.kind in (Kind.PERIPHERAL, Kind.CORE):
            bus = buses[r.bus]
            assert bus.base <= r.base and r.base + r.size <= bus.base + bus.size, r.name


def test_the_vector_table_is_rm0383s():
    assert max(VECTORS.values()) == NUM_IRQS - 1
    assert len(set(VECTORS.values())) == len(VECTORS)
    assert (VECTORS["TIM1_BRK_TIM9"], VECTORS["TIM1_UP_TIM10"],
            VECTORS["TIM1_TRG_COM_TIM11"], VECTORS["TIM1_CC"]) == (24, 25, 26, 27)
    for name, irq in IRQS.items():            # the hand-written models' numbers
        if isinstance(irq, tuple):            # a DMA controller's streams
            assert irq == platform.row(name).irq_numbers, name
        else:
            assert irq == VECTORS[name], name


def test_clock_gates_come_from_the_table():
    assert CLOCK_BITS == platform.clock_bits()
    # RM0383 6.3.9-6.3.12, the gates the hand-written models had before the table
    assert {n: CLOCK_BITS[n] for n in ("GPIOA", "DMA2", "TIM5", "USART2", "PWR", "USART6",
                                       "SYSCFG")} == {
        "GPIOA": (0x30, 0), "DMA2": (0x30, 22), "TIM5": (0x40, 3), "USART2": (0x40, 17),
        "PWR": (0x40, 28), "USART6": (0x44, 5), "SYSCFG": (0x44, 14)}
    assert CLOCK_BITS["TIM1"] == (0x44, 0) and CLOCK_BITS["TIM11"] == (0x44, 18)


def test_every_model_resolves():
    for r in PLATFORM:
        if r.model:
            assert platform.model_of(r) is not None, r.name


def test_the_docs_table_is_the_generators():
    page = platform.DOCS.read_text()
    assert platform.documented(page) == platform.markdown(), (
        "docs/elf-firmware.md's platform table is stale: run python -c "
        "'from hil.mcu import platform; platform.write_docs()'")
