"""GPIO's register map (RM0383 8.4) and the robot's wiring to it: the offsets that the port
model (gpio.py) and the board core's PA1 turns and PB reads (board_core.c, through
board_layout.py) use."""
from __future__ import annotations

MODER, OTYPER, OSPEEDR, PUPDR, IDR, ODR, BSRR, LCKR, AFRL, AFRH = range(0, 0x28, 4)
DIRECTION_PIN = 1            # PA1: the servo line's direction buffer
SWITCH_PINS = 6              # PB0-PB5
