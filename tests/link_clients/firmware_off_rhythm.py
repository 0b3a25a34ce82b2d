# The real firmware off its rhythm now and then (tests/test_lookahead.py): every 5th sleep
# 4 ms early, and every 7th cycle an LED write between its status reads and its sleep. The
# host's lookahead steps the world ahead after the reads; here it must take the steps
# back, and the run must be the one it would have been without them.
import sys

from firmware import main
from firmware.hal import sim
from protocol.dynamixel import v1 as dxl

_sleep_until = sim.Board.sleep_until
_cycles = [0]


def sleep_until(board, t_us):
    _cycles[0] += 1
    n = _cycles[0]
    if n % 7 == 0:
        packet = dxl.write(1, 25, bytes((n & 1,)))   # AX-12 LED, address 25
        board.uart.write(packet, len(packet))
    _sleep_until(board, t_us - 4000 if n % 5 == 0 else t_us)


sim.Board.sleep_until = sleep_until
sys.exit(main.start())
