# A firmware that only echoes: each CAN frame the host queued for it comes back with its ID
# + ECHO_ID_OFFSET, in the order received, at the cycle it arrived (tests/test_link_burst.py).
# The link client is firmware/hal/sim.py, as in firmware/main.py.
from firmware.hal import sim

ECHO_ID_OFFSET = 0x400
CYCLE_US = 20000

board = sim.Board()
while not board.ended:
    board.sleep_until(board.ticks_add(board.ticks_us(), CYCLE_US))
    while board.can.any():
        arb_id, data = board.can.recv()
        board.can.send(data, arb_id + ECHO_ID_OFFSET)
board.close()
