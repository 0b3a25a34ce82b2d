"""The emulated STM32F411: an unchanged Cortex-M4F ELF in lockstep with the robot.

``elf_image`` reads and checks the ELF; ``core`` runs it on Unicorn in chunks of exact
instruction counts (one instruction is one cycle of HCLK) and does the exception model
Unicorn leaves out (``armv7m`` holds the architecture's numbers), at the virtual time of
``timebase``; ``system`` (NVIC,
SCB, DWT), ``systick``, ``rcc``, ``gpio``, ``usart`` and ``peripherals`` (TIM1-5, TIM9-11,
DMA, bxCAN1) are the board's peripherals at register level (facts from RM0383), with
``flash`` (the FLASH interface: erase and programming) and ``rtc`` (the calendar, the backup
registers); ``registers`` describes a peripheral's registers as data and is the generic
register file, ``devices`` holds the peripherals built that way (IWDG, WWDG, CRC, ADC1, I2C,
SPI, SDIO), ``platform`` is the table of every region and peripheral (address, model, IRQs,
clock gate); ``flash_fs`` lays and reads back MicroPython's /flash, ``deadline`` measures
the busy time per control cycle; ``board`` joins them,
``servo_line`` wires USART2 to the servo bus through the PA1 direction buffer, ``console``
takes USART1/6 and semihosting, ``poll`` skips waiting, and ``link_client`` speaks the
simulator link as a client, so the line, switches, CAN and console reach hil/link/ as any
runtime's do. ``runtime`` serves an ELF in a run, ``replayed`` under ``hexhil replay``;
``gdb`` is ``--gdb``, ``coverage`` is ``--coverage``. ``board_core`` is the hot path
compiled (the event heap that schedules what the peripherals will do, USART2, SysTick's
wraps, the exception model's entry, return and choice, the run loop), whose struct and
shared constants ``board_layout`` writes once. docs/elf-firmware.md is the page.
"""
