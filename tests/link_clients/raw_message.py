# A client that posts one raw message, `raw_message.py OP HEXPAYLOAD` (op in hex), then
# sleeps (tests/test_link_errors.py): the host must answer an unknown or malformed message
# with an error reply.
import sys

from firmware import main
from firmware.hal import sim


def run():
    op, payload = int(sys.argv[1], 16), bytes.fromhex(sys.argv[2]) if len(sys.argv) > 2 else b""
    board = sim.Board()
    board.link.post(op, payload, len(payload))
    board.sleep_until(board.ticks_add(board.ticks_us(), 20000))
    board.close()


sys.exit(main.start(run))
