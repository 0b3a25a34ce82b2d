"""USART1/2/6's register map (RM0383 19.6): the offsets and bits that the register model
(usart.py) and the board core's USART2 (board_core.c, through board_layout.py) use."""
from __future__ import annotations

SR, DR, BRR, CR1, CR2, CR3, GTPR = range(0, 0x1C, 4)
# SR
PE, FE, NF, ORE, IDLE, RXNE, TC, TXE, LBD, CTS = (1 << i for i in range(10))
# CR1
UE, M_9BIT, OVER8 = 1 << 13, 1 << 12, 1 << 15
TE, RE, IDLEIE, RXNEIE, TCIE, TXEIE = 1 << 3, 1 << 2, 1 << 4, 1 << 5, 1 << 6, 1 << 7
# CR3
EIE, HDSEL, DMAR, DMAT = 1 << 0, 1 << 3, 1 << 6, 1 << 7
# CR2's STOP field (bits 13:12) -> the stop bits in half bits: 1, 0.5, 2, 1.5
STOP_SHIFT = 12
STOP_HALF_BITS = (2, 1, 4, 3)
