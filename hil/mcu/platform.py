"""The STM32F411 as a table (RM0383 2.3's memory map, 10.2's vector table, 6.3.9-6.3.12's
clock enables): one row per region and peripheral with its base, size, model, interrupt
lines and RCC clock gate.

A row's ``model`` names what answers there, ``module:attribute``: a ``Description``
(hil/mcu/registers.py) gets the generic register file; a callable ``(board, row)``
builds the peripheral. Rows the board builds itself (``Built.BOARD``: the core's, RCC,
GPIOA-C, the USARTs, EXTI, SYSCFG, TIM2-5, DMA, bxCAN1, FLASH, PWR and RTC) name the model
hil/mcu/board.py makes for them. ``build`` makes the ``Built.TABLE`` rows for a board;
``clock_bits`` is rcc.py's ``CLOCK_BITS``; ``markdown`` is docs/elf-firmware.md's table.
Adding a peripheral is a file (its description and behaviour) and a row here.
"""
from __future__ import annotations

import enum
import importlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hexhil.hil.mcu.registers import Description, RegisterFile


class Kind(enum.Enum):
    MEMORY = "memory"
    ALIAS = "bit-band alias"
    BUS = "bus"
    PERIPHERAL = "peripheral"
    CORE = "core peripheral"


class Built(enum.Enum):
    BOARD = "board"      # hil/mcu/board.py makes it
    TABLE = "table"      # ``build`` makes it from the row
    NONE = "none"        # listed, not modelled


ENABLE_REGISTERS = {"AHB1ENR": 0x30, "AHB2ENR": 0x34, "APB1ENR": 0x40, "APB2ENR": 0x44}

# RM0383 table 37: the F411's interrupt positions (CAN1's four are the F4 family's, for the
# bxCAN1 modelled beyond the F411: see hil/mcu/peripherals.py)
VECTORS: dict[str, int] = {
    "WWDG": 0, "PVD": 1, "TAMP_STAMP": 2, "RTC_WKUP": 3, "FLASH": 4, "RCC": 5,
    "EXTI0": 6, "EXTI1": 7, "EXTI2": 8, "EXTI3": 9, "EXTI4": 10,
    **{f"DMA1_Stream{i}": 11 + i for i in range(7)}, "ADC": 18,
    "CAN1_TX": 19, "CAN1_RX0": 20, "CAN1_RX1": 21, "CAN1_SCE": 22, "EXTI9_5": 23,
    "TIM1_BRK_TIM9": 24, "TIM1_UP_TIM10": 25, "TIM1_TRG_COM_TIM11": 26, "TIM1_CC": 27,
    "TIM2": 28, "TIM3": 29, "TIM4": 30, "I2C1_EV": 31, "I2C1_ER": 32, "I2C2_EV": 33,
    "I2C2_ER": 34, "SPI1": 35, "SPI2": 36, "USART1": 37, "USART2": 38, "EXTI15_10": 40,
    "RTC_Alarm": 41, "OTG_FS_WKUP": 42, "DMA1_Stream7": 47, "SDIO": 49, "TIM5": 50,
    "SPI3": 51, **{f"DMA2_Stream{i}": 56 + i for i in range(5)}, "OTG_FS": 67,
    **{f"DMA2_Stream{i}": 63 + i for i in range(5, 8)}, "USART6": 71, "I2C3_EV": 72,
    "I2C3_ER": 73, "FPU": 81, "SPI4": 84, "SPI5": 85,
}
NUM_IRQS = 86                 # the NVIC's interrupt positions: 0..85
PRIORITY_BITS = 0xF0          # the 4 priority bits of an NVIC or SCB priority byte (PM0214 4.3.7)


@dataclass(frozen=True)
class Row:
    name: str
    base: int
    size: int
    kind: Kind
    bus: str = ""
    model: str = ""                          # module:attribute
    built: Built = Built.NONE
    irqs: tuple[str, ...] = ()               # VECTORS names
    clock: tuple[str, int] | None = None     # (RCC enable register, bit)
    does: str = ""                           # what the model does, for the docs

    @property
    def irq_numbers(self) -> tuple[int, ...]:
        return tuple(VECTORS[n] for n in self.irqs)


def _p(name: str, base: int, bus: str, model: str, built: Built = Built.TABLE,
       irqs: tuple[str, ...] = (), clock: tuple[str, int] | None = None,
       does: str = "") -> Row:
    return Row(name, base, 0x400, Kind.PERIPHERAL, bus, model, built, irqs, clock, does)


B, T = Built.BOARD, Built.TABLE
REGISTERS_ONLY = "registers as data: reset values and access rules, no behaviour"
I2C_DOES = "a master on a bus with no device: START, the address not acknowledged (AF), STOP"
PLATFORM: tuple[Row, ...] = (
    Row("Flash", 0x08000000, 0x80000, Kind.MEMORY, "", "hexhil.hil.mcu.core:Core", B,
        does="512 KB, also at 0 (BOOT0 low); what the ELF leaves reads 0xFF (erased); "
        "a store programs it only through the FLASH interface (below)"),
    Row("System memory", 0x1FFF0000, 0x7800, Kind.MEMORY, "", "hexhil.hil.mcu.device_id:attach", B,
        does="read-only; the bootloader's code is not there (reads 0)"),
    Row("OTP", 0x1FFF7800, 0x210, Kind.MEMORY, "", "hexhil.hil.mcu.device_id:attach", B,
        does="read-only, erased (0xFF)"),
    Row("Unique ID, flash size", 0x1FFF7A10, 0x14, Kind.MEMORY, "", "hexhil.hil.mcu.device_id:attach",
        B, does="a fixed 96-bit ID (the same every run) at 0x1FFF7A10, 512 (KB) at 0x1FFF7A22"),
    Row("Option bytes", 0x1FFFC000, 0x10, Kind.MEMORY, does="not mapped"),
    Row("SRAM", 0x20000000, 0x20000, Kind.MEMORY, "", "hexhil.hil.mcu.core:Core", B, does="128 KB"),
    Row("SRAM bit-band", 0x22000000, 0x400000, Kind.ALIAS, "", "hexhil.hil.mcu.bitband:BitBandAlias",
        B, does="a word per SRAM bit (PM0214 2.2.5)"),
    Row("APB1", 0x40000000, 0x8000, Kind.BUS, "APB1"),
    Row("APB2", 0x40010000, 0x5800, Kind.BUS, "APB2"),
    Row("AHB1", 0x40020000, 0x60000, Kind.BUS, "AHB1"),
    Row("Peripheral bit-band", 0x42000000, 0x1000000, Kind.ALIAS, "",
        "hexhil.hil.mcu.bitband:BitBandAlias", B,
        does="a word per bit of APB1/APB2/AHB1: a read-modify-write of the register "
        "through its model"),
    Row("AHB2", 0x50000000, 0x40000, Kind.BUS, "AHB2"),
    Row("PPB", 0xE0000000, 0x100000, Kind.BUS, "PPB"),
    # APB1
    _p("TIM2", 0x40000000, "APB1", "hexhil.hil.mcu.peripherals:BasicTimer", B, ("TIM2",),
       ("APB1ENR", 0), "32-bit; see TIM1-5, TIM9-11"),
    _p("TIM3", 0x40000400, "APB1", "hexhil.hil.mcu.peripherals:BasicTimer", B, ("TIM3",),
       ("APB1ENR", 1), "16-bit"),
    _p("TIM4", 0x40000800, "APB1", "hexhil.hil.mcu.peripherals:BasicTimer", B, ("TIM4",),
       ("APB1ENR", 2), "16-bit"),
    _p("TIM5", 0x40000C00, "APB1", "hexhil.hil.mcu.peripherals:BasicTimer", B, ("TIM5",),
       ("APB1ENR", 3), "32-bit"),
    _p("RTC", 0x40002800, "APB1", "hexhil.hil.mcu.rtc:Rtc", B,
       ("RTC_WKUP", "RTC_Alarm", "TAMP_STAMP"), does="the calendar TR/DR/SSR in virtual "
       "time from RTCSEL's clock with RTCEN, PRER; WPR's key, PWR DBP, INIT/INITF/RSF/INITS, "
       "the shadow lock of TR/DR; BKP0R-BKP19R; not alarms, wake-up, tamper, BDRST"),
    _p("WWDG", 0x40002C00, "APB1", "hexhil.hil.mcu.devices.wwdg:Wwdg", T, ("WWDG",),
       ("APB1ENR", 11), "the 7-bit counter on PCLK1/4096/2^WDGTB, WDGA, the window: a "
       "timeout or an early refresh resets the MCU (named, counted); EWIF and its interrupt"),
    _p("IWDG", 0x40003000, "APB1", "hexhil.hil.mcu.devices.iwdg:Iwdg", T,
       does="keys 0xCCCC/0xAAAA/0x5555, PR and RLR on LSI 32 kHz, PVU/RVU for 5 LSI "
       "periods: a timeout resets the MCU (named, counted)"),
    _p("I2S2ext", 0x40003400, "APB1", "hexhil.hil.mcu.devices.spi:SPI", T, clock=("APB1ENR", 14),
       does=REGISTERS_ONLY),
    _p("SPI2", 0x40003800, "APB1", "hexhil.hil.mcu.devices.spi:SPI", T, ("SPI2",), ("APB1ENR", 14),
       REGISTERS_ONLY),
    _p("SPI3", 0x40003C00, "APB1", "hexhil.hil.mcu.devices.spi:SPI", T, ("SPI3",), ("APB1ENR", 15),
       REGISTERS_ONLY),
    _p("I2S3ext", 0x40004000, "APB1", "hexhil.hil.mcu.devices.spi:SPI", T, clock=("APB1ENR", 15),
       does=REGISTERS_ONLY),
    _p("USART2", 0x40004400, "APB1", "hexhil.hil.mcu.usart:Usart", B, ("USART2",),
       ("APB1ENR", 17), "the servo line; see USART1/2/6"),
    _p("I2C1", 0x40005400, "APB1", "hexhil.hil.mcu.devices.i2c:I2cBus", T, ("I2C1_EV", "I2C1_ER"),
       ("APB1ENR", 21), I2C_DOES),
    _p("I2C2", 0x40005800, "APB1", "hexhil.hil.mcu.devices.i2c:I2cBus", T, ("I2C2_EV", "I2C2_ER"),
       ("APB1ENR", 22), I2C_DOES),
    _p("I2C3", 0x40005C00, "APB1", "hexhil.hil.mcu.devices.i2c:I2cBus", T, ("I2C3_EV", "I2C3_ER"),
       ("APB1ENR", 23), I2C_DOES),
    _p("CAN1", 0x40006400, "APB1", "hexhil.hil.mcu.peripherals:BxCan", B,
       ("CAN1_TX", "CAN1_RX0", "CAN1_RX1", "CAN1_SCE"), ("APB1ENR", 25),
       "**not on the F411**: the F4 family's bxCAN1, for CAN firmware of a bigger F4; "
       "init/sleep handshakes, three TX mailboxes, FIFO 0 of three frames, FMPIE0/TMEIE"),
    _p("PWR", 0x40007000, "APB1", "hexhil.hil.mcu.rcc:power", B, ("PVD",), ("APB1ENR", 28),
       "CR, CSR: VOSRDY, the backup regulator ready (BRR) once BRE is set"),
    # APB2
    _p("TIM1", 0x40010000, "APB2", "hexhil.hil.mcu.peripherals:apb2_timer", T,
       ("TIM1_UP_TIM10", "TIM1_CC", "TIM1_BRK_TIM9", "TIM1_TRG_COM_TIM11"), ("APB2ENR", 0),
       "16-bit on APB2's timer clock: update at ARR, PSC, CC1-4 flags, their interrupts "
       "(a HAL timebase)"),
    _p("USART1", 0x40011000, "APB2", "hexhil.hil.mcu.usart:Usart", B, ("USART1",), ("APB2ENR", 4),
       "the console; see USART1/2/6"),
    _p("USART6", 0x40011400, "APB2", "hexhil.hil.mcu.usart:Usart", B, ("USART6",), ("APB2ENR", 5),
       "a second console; see USART1/2/6"),
    _p("ADC1", 0x40012000, "APB2", "hexhil.hil.mcu.devices.adc:Adc", T, ("ADC",), ("APB2ENR", 8),
       "a regular conversion by SWSTART (CONT), EOC and its interrupt after the sampling "
       "time; VREFINT, the temperature sensor, VBAT/4; the pins read 0 V; not scan, "
       "injected, triggers, DMA"),
    _p("SDIO", 0x40012C00, "APB2", "hexhil.hil.mcu.devices.sdio:SDIO", T, ("SDIO",),
       ("APB2ENR", 11), "no registers: each access named, reads 0"),
    _p("SPI1", 0x40013000, "APB2", "hexhil.hil.mcu.devices.spi:SPI", T, ("SPI1",), ("APB2ENR", 12),
       REGISTERS_ONLY),
    _p("SPI4", 0x40013400, "APB2", "hexhil.hil.mcu.devices.spi:SPI", T, ("SPI4",), ("APB2ENR", 13),
       REGISTERS_ONLY),
    _p("SYSCFG", 0x40013800, "APB2", "hexhil.hil.mcu.gpio:Syscfg", B, (), ("APB2ENR", 14),
       "EXTICR1-4 route EXTI lines 0-15; the rest keeps what is written"),
    _p("EXTI", 0x40013C00, "APB2", "hexhil.hil.mcu.gpio:Exti", B,
       ("EXTI0", "EXTI1", "EXTI2", "EXTI3", "EXTI4", "EXTI9_5", "EXTI15_10"),
       does="IMR, RTSR/FTSR, SWIER, PR (lines 0-15); not EMR, lines 16-22"),
    _p("TIM9", 0x40014000, "APB2", "hexhil.hil.mcu.peripherals:apb2_timer", T, ("TIM1_BRK_TIM9",),
       ("APB2ENR", 16), "16-bit on APB2, CC1-2; as TIM1"),
    _p("TIM10", 0x40014400, "APB2", "hexhil.hil.mcu.peripherals:apb2_timer", T, ("TIM1_UP_TIM10",),
       ("APB2ENR", 17), "16-bit on APB2, CC1; as TIM1"),
    _p("TIM11", 0x40014800, "APB2", "hexhil.hil.mcu.peripherals:apb2_timer", T,
       ("TIM1_TRG_COM_TIM11",), ("APB2ENR", 18), "16-bit on APB2, CC1; as TIM1"),
    _p("SPI5", 0x40015000, "APB2", "hexhil.hil.mcu.devices.spi:SPI", T, ("SPI5",), ("APB2ENR", 20),
       REGISTERS_ONLY),
    # AHB1
    _p("GPIOA", 0x40020000, "AHB1", "hexhil.hil.mcu.gpio:GpioPort", B, (), ("AHB1ENR", 0),
       "PA1 drives the servo line's direction buffer; see GPIO"),
    _p("GPIOB", 0x40020400, "AHB1", "hexhil.hil.mcu.gpio:GpioPort", B, (), ("AHB1ENR", 1),
       "PB0-PB5: the leg switches to ground; see GPIO"),
    _p("GPIOC", 0x40020800, "AHB1", "hexhil.hil.mcu.gpio:GpioPort", B, (), ("AHB1ENR", 2), "see GPIO"),
    _p("GPIOD", 0x40020C00, "AHB1", "hexhil.hil.mcu.gpio:other_port", T, (), ("AHB1ENR", 3),
       "see GPIO"),
    _p("GPIOE", 0x40021000, "AHB1", "hexhil.hil.mcu.gpio:other_port", T, (), ("AHB1ENR", 4),
       "see GPIO"),
    _p("GPIOH", 0x40021C00, "AHB1", "hexhil.hil.mcu.gpio:other_port", T, (), ("AHB1ENR", 7),
       "see GPIO"),
    _p("CRC", 0x40023000, "AHB1", "hexhil.hil.mcu.devices.crc:Crc", T, (), ("AHB1ENR", 12),
       "CRC-32 (0x04C11DB7) of the words written to DR, CR RESET"),
    _p("RCC", 0x40023800, "AHB1", "hexhil.hil.mcu.rcc:Rcc", B, ("RCC",),
       does="HSI 16 MHz, HSE 25 MHz, PLL (M/N/P), LSI/LSE ready bits, ready 100 us after "
       "ON, SW/SWS, HPRE/PPRE1/PPRE2, the enable bits (a peripheral with its clock off "
       "reads 0 and ignores writes), CSR's reset flags (IWDG, WWDG, software) and RMVF; "
       "not PLLI2S, CSS"),
    _p("FLASH", 0x40023C00, "AHB1", "hexhil.hil.mcu.flash:FlashInterface", B, ("FLASH",),
       does="KEYR's unlock sequence, CR PG/SER/MER/SNB/PSIZE/STRT/LOCK/EOPIE/ERRIE, SR BSY "
       "for the datasheet's typical times, EOP and the error flags (write 1 to clear), its "
       "interrupt; sector erase to 0xFF, programming by a store while PG is set (bits 1 to "
       "0 only); ACR keeps what is written (no wait states modelled)"),
    _p("DMA1", 0x40026000, "AHB1", "hexhil.hil.mcu.peripherals:Dma", B,
       tuple(f"DMA1_Stream{i}" for i in range(8)), ("AHB1ENR", 21),
       "the USARTs' streams and channels, byte transfers, MINC, CIRC, NDTR counting "
       "down, HT/TC and their interrupts; not memory-to-memory, FIFO, bursts, double "
       "buffer"),
    _p("DMA2", 0x40026400, "AHB1", "hexhil.hil.mcu.peripherals:Dma", B,
       tuple(f"DMA2_Stream{i}" for i in range(8)), ("AHB1ENR", 22), "as DMA1"),
    # AHB2
    Row("USB OTG FS", 0x50000000, 0x40000, Kind.PERIPHERAL, "AHB2", "", Built.NONE,
        ("OTG_FS", "OTG_FS_WKUP"), ("AHB2ENR", 7), "not mapped (an access is a fault)"),
    # the core's (hil/mcu/system.py)
    Row("DWT", 0xE0001000, 0x1000, Kind.CORE, "PPB", "hexhil.hil.mcu.system:SystemBlock", B,
        does="CTRL CYCCNTENA, CYCCNT"),
    Row("SysTick", 0xE000E010, 0x10, Kind.CORE, "PPB", "hexhil.hil.mcu.systick:SysTick", B,
        does="CSR (HCLK or HCLK/8, TICKINT, COUNTFLAG), RVR, CVR"),
    Row("NVIC", 0xE000E100, 0x400, Kind.CORE, "PPB", "hexhil.hil.mcu.system:Nvic", B,
        does="ISER/ICER/ISPR/ICPR/IABR, IPR (4 bits), STIR; PRIGROUP, PRIMASK/BASEPRI/"
        "FAULTMASK, tail-chaining, level lines"),
    Row("SCB", 0xE000ED00, 0x90, Kind.CORE, "PPB", "hexhil.hil.mcu.system:SystemBlock", B,
        does="CPUID, ICSR, VTOR, AIRCR (PRIGROUP, SYSRESETREQ), SCR (SLEEPONEXIT; "
        "SLEEPDEEP and SEVONPEND kept: Stop and Standby not modelled, named once in the log), "
        "SHPR1-3, SHCSR, CFSR, HFSR, MMFAR, BFAR (hil/mcu/faults.py), CPACR; not the MPU"),
    Row("DBGMCU", 0xE0042000, 0x10, Kind.CORE, "PPB", "hexhil.hil.mcu.system:SystemBlock", B,
        does="IDCODE (DEV_ID 0x431, REV_ID 0x1000); CR and the freeze bits kept as written"),
    Row("FPU", 0xE000EF30, 0x10, Kind.CORE, "PPB", "hexhil.hil.mcu.system:SystemBlock", B,
        ("FPU",), does="FPCCR, FPCAR kept as written"),
)


def rows(built: Built | None = None) -> tuple[Row, ...]:
    return tuple(r for r in PLATFORM if built is None or r.built is built)


def row(name: str) -> Row:
    for r in PLATFORM:
        if r.name == name:
            return r
    raise KeyError(name)


def clock_bits() -> dict[str, tuple[int, int]]:
    """(RCC enable register offset, bit) of each gated peripheral (rcc.py's CLOCK_BITS)."""
    return {r.name: (ENABLE_REGISTERS[r.clock[0]], r.clock[1])
            for r in PLATFORM if r.clock is not None}


def model_of(r: Row) -> Any:
    module, _, attr = r.model.partition(":")
    return getattr(importlib.import_module(module), attr)


def make(board: Any, r: Row) -> Any:
    """The peripheral of a ``Built.TABLE`` row for ``board``."""
    model = model_of(r)
    if isinstance(model, Description):
        return RegisterFile(model.renamed(r.name), board.noted)
    return model(board, r)


def build(board: Any) -> list[Any]:
    """The peripheral of every ``Built.TABLE`` row, in the table's order (the board maps
    each at its row's base)."""
    return [make(board, r) for r in rows(Built.TABLE)]


def markdown() -> str:
    """The table of docs/elf-firmware.md ("What the emulated board models")."""
    lines = ["| Name | Address | Size | Bus | Model | IRQs | Clock | Modelled |",
             "|---|---|---|---|---|---|---|---|"]
    for r in PLATFORM:
        if r.kind is Kind.BUS:
            continue
        model = f"`{r.model.replace(':', '.')}`" if r.model else "-"
        irqs = ", ".join(f"{n} ({VECTORS[n]})" for n in r.irqs) or "-"
        clock = f"{r.clock[0]}.{r.clock[1]}" if r.clock else "-"
        size = f"{r.size // 1024} KB" if r.size >= 1024 else f"{r.size} B"
        lines.append(f"| {r.name} | 0x{r.base:08X} | {size} | {r.bus or '-'} | {model} | "
                     f"{irqs} | {clock} | {r.does} |")
    return "\n".join(lines) + "\n"


DOCS = Path(__file__).resolve().parents[2] / "docs" / "elf-firmware.md"
BEGIN = "<!-- platform table: generated by hil/mcu/platform.py markdown() -->\n"
END = "<!-- end of the platform table -->\n"


def documented(page: str) -> str:
    """The platform table as ``page`` (docs/elf-firmware.md's text) has it."""
    return page[page.index(BEGIN) + len(BEGIN):page.index(END)]


def write_docs(path: Path = DOCS) -> None:
    """Rewrite docs/elf-firmware.md's platform table from ``markdown()``."""
    page = path.read_text()
    path.write_text(page.replace(BEGIN + documented(page) + END, BEGIN + markdown() + END))
