# A client that posts one raw message, `raw_message.py OP HEXPAYLOAD [v1]` (op in hex), then
# sleeps (tests/test_link_errors.py): the host must answer an unknown or malformed message
# with an error reply. With `v1` it offers link version 1 only.
import sys

from firmware import main
from firmware.hal import sim
from protocol import sim_link

if sys.argv[-1] == "v1":
    sys.argv.pop()
    sim_link.VERSIONS = (sim_link.VERSION,)


def run():
    op, payload = int(sys.argv[1], 16), bytes.fromhex(sys.argv[2]) if len(sys.argv) > 2 else b""
    board = sim.Board()
    board.link.post(op, payload, len(payload))
    board.sleep_until(board.ticks_add(board.ticks_us(), 20000))
    board.close()


sys.exit(main.start(run))
