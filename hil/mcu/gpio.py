"""GPIOA-C, EXTI and SYSCFG's EXTI selection (RM0383 8, 10, 7), wired as on the robot.

PA1 drives the 74HC126/74HC04 direction buffer of the servo line (high: transmit); it
counts only while PA1 is an output. PB0-PB5 are the six leg switches to ground: a pressed
switch reads 0, a released one reads 1 through the pin's pull-up (PUPDR 01) and 0 without
one (the board has no pull-up resistors of its own). Any other input reads its pull: 1
with a pull-up, else 0. A switch edge sets EXTI's pending bit when SYSCFG routes that line
to port B and the edge is enabled in RTSR/FTSR; IMR passes it to the NVIC.
"""
from __future__ import annotations

from typing import Any, Callable

from hexhil.hil.mcu.board_core import library
from hexhil.hil.mcu.gpio_registers import (AFRH, AFRL, BSRR, IDR, LCKR, MODER, ODR, OSPEEDR,
                                           OTYPER, PUPDR)
from hexhil.hil.mcu.platform import VECTORS

RESET = {"GPIOA": {MODER: 0xA8000000, OSPEEDR: 0x0C000000, PUPDR: 0x64000000},
         "GPIOB": {MODER: 0x00000280, OSPEEDR: 0x000000C0, PUPDR: 0x00000100}}
# the interrupt each EXTI line raises: 0-4 their own, 5-9 and 10-15 one shared each
EXTI_IRQS = tuple(VECTORS[f"EXTI{i}"] for i in range(5)) + (VECTORS["EXTI9_5"],) * 5 + \
    (VECTORS["EXTI15_10"],) * 6


class SharedRegisters(dict):
    """A port's registers where MODER, PUPDR and ODR live in the compiled board's shared
    state (hil/mcu/board_core.py ``Shared``): board_core.c turns PA1 and reads the
    switches on PB itself."""

    def __init__(self, values: dict[int, int], shared: Any, port: int) -> None:
        super().__init__(values)
        self._port = port
        self._arrays = {MODER: shared.gpio_moder, PUPDR: shared.gpio_pupdr, ODR: shared.gpio_odr}
        for off, array in self._arrays.items():
            array[port] = dict.pop(self, off)

    def __getitem__(self, off: int) -> int:
        array = self._arrays.get(off)
        return dict.__getitem__(self, off) if array is None else array[self._port]

    def __setitem__(self, off: int, value: int) -> None:
        array = self._arrays.get(off)
        if array is None:
            dict.__setitem__(self, off, value)
        else:
            array[self._port] = value

    def get(self, off: int, default: Any = None) -> Any:
        array = self._arrays.get(off)
        return dict.get(self, off, default) if array is None else array[self._port]


class GpioPort:
    """One port; ``grounded()`` is the mask of its pins that something outside pulls to
    ground (the board's pressed switches); ``shared``, the board core's state (ports A-C)."""

    pollable = frozenset({IDR, ODR})

    def __init__(self, name: str, index: int, on_output: Callable[["GpioPort", int], None],
                 grounded: Callable[[], int], shared: Any = None) -> None:
        self.name, self.index = name, index
        self.on_output, self.grounded = on_output, grounded
        self._idr, self._odr_after = library().bc_idr, library().bc_odr_after
        self.before_input: Callable[[], None] | None = None    # IDR is about to be read
        regs = {MODER: 0, OTYPER: 0, OSPEEDR: 0, PUPDR: 0, ODR: 0, LCKR: 0, AFRL: 0, AFRH: 0,
                **RESET.get(name, {})}
        self.regs = regs if shared is None else SharedRegisters(regs, shared, index)

    def mode(self, pin: int) -> int:
        return (self.regs[MODER] >> 2 * pin) & 3

    def idr(self) -> int:
        """All 16 pins' levels (board_core.c ``bc_idr``): outputs read ODR, analog pins 0,
        inputs and alternate functions 0 where grounded, else their pull-up."""
        return self._idr(self.regs[MODER], self.regs[PUPDR], self.regs[ODR], self.grounded())

    def output(self, pin: int) -> int:
        """The level the port drives on ``pin`` (0 unless it is an output)."""
        return (self.regs[ODR] >> pin) & 1 if self.mode(pin) == 1 else 0

    def read(self, off: int) -> int:
        if off == IDR:
            if self.before_input is not None:
                self.before_input()
            return self.idr()
        return self.regs.get(off, 0) if off != BSRR else 0

    def write(self, off: int, value: int) -> None:
        old = self.regs[ODR]
        if off in (ODR, BSRR):        # board_core.c ``bc_odr_after``: set wins
            self.regs[ODR] = self._odr_after(old, off, value)
        elif off == IDR:
            return
        else:
            self.regs[off] = value & 0xFFFFFFFF
        self.on_output(self, old)


def other_port(board: Any, row: Any) -> GpioPort:
    """GPIOD, E or H from its platform row (hil/mcu/platform.py): nothing is wired to
    them on the robot's board."""
    return GpioPort(row.name, (row.base - 0x40020000) // 0x400, lambda port, old: None,
                    lambda: 0)


class Exti:
    """EXTI lines 0-15 from GPIO pins (SYSCFG_EXTICRx picks the port), to the NVIC."""

    name = "EXTI"
    pollable = frozenset({0x14})

    def __init__(self, line: Callable[[int, bool], None]) -> None:
        self.line = line
        self.regs = {0x00: 0, 0x04: 0, 0x08: 0, 0x0C: 0, 0x10: 0, 0x14: 0}
        self.exticr = [0, 0, 0, 0]

    def port_of(self, line: int) -> int:
        return (self.exticr[line // 4] >> 4 * (line % 4)) & 0xF

    def edge(self, port: int, pin: int, rising: bool) -> None:
        """Pin ``pin`` of port ``port`` (0 = A) changed level."""
        if self.port_of(pin) != port:
            return
        if self.regs[0x08 if rising else 0x0C] >> pin & 1:
            self.regs[0x14] |= 1 << pin
            self._lines()

    def _lines(self) -> None:
        active = self.regs[0x14] & self.regs[0x00]
        for irq in set(EXTI_IRQS):
            self.line(irq, any(active >> i & 1 for i in range(16) if EXTI_IRQS[i] == irq))

    def read(self, off: int) -> int:
        return self.regs.get(off, 0)

    def write(self, off: int, value: int) -> None:
        if off == 0x14:
            self.regs[0x14] &= ~value
        elif off == 0x10:
            self.regs[0x14] |= value & self.regs[0x00] & 0x7FFFFF
        elif off in self.regs:
            self.regs[off] = value & 0x7FFFFF
        self._lines()


class Syscfg:
    """SYSCFG: EXTICR1-4 route EXTI lines to ports; the rest keeps what is written."""

    name = "SYSCFG"
    pollable = frozenset()

    def __init__(self, exti: Exti) -> None:
        self.exti = exti
        self.regs: dict[int, int] = {}

    def read(self, off: int) -> int:
        if 0x08 <= off <= 0x14:
            return self.exti.exticr[(off - 0x08) // 4]
        return self.regs.get(off, 0)

    def write(self, off: int, value: int) -> None:
        if 0x08 <= off <= 0x14:
            self.exti.exticr[(off - 0x08) // 4] = value & 0xFFFF
        else:
            self.regs[off] = value
