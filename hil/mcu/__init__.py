"""The emulated STM32F411 (issue 40): an unchanged Cortex-M4F ELF in lockstep with the robot.

``elf_image`` reads and checks the ELF; ``core`` runs it on Unicorn in chunks of exact
instruction counts (one instruction is one cycle of HCLK) and does the exception model
Unicorn leaves out; ``system`` (NVIC, SCB, SysTick, DWT), ``rcc``, ``gpio``, ``usart``,
``timers``, ``dma`` and ``bxcan`` are the board's peripherals at register level (facts from
RM0383); ``board`` joins them and speaks the simulator link (protocol/sim_link.py) as a
client, so the line, switches, CAN and console reach hil/link/ like any other runtime's;
``runtime`` is the ``--firmware fw.elf`` runtime. docs/elf-firmware.md is the user's page.
"""
