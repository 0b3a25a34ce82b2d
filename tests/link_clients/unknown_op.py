# A client that posts a message of an op no link version defines, then sleeps
# (tests/test_link_errors.py): the host must answer with an error reply.
import sys

from firmware import main
from firmware.hal import sim

PROBE_OP = 0x7A


def run():
    board = sim.Board()
    board.link.post(PROBE_OP, b"??", 2)
    board.sleep_until(board.ticks_add(board.ticks_us(), 20000))
    board.close()


sys.exit(main.start(run))
