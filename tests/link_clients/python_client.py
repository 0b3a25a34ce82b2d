# The conformance script (docs/link.md "Conformance suite") spoken by the Python link client,
# firmware/hal/sim.py, under micropython or CPython: hil/link/client_conformance.py serves it.
# `--drop-more` makes a deliberately broken client that ignores FLAG_MORE (the suite must
# catch it: tests/test_link_conformance.py).
import sys

from firmware import main
from firmware.hal import sim
from protocol import sim_link

PROBE_OP = 0x7A          # an op no version of the link defines
CYCLE_US = 20000


def run(drop_more):
    board = sim.Board()
    link = board.link
    cfg = board.config()
    if cfg.get("probe") == "unknown_op":
        link.post(PROBE_OP, b"", 0)
    token = cfg.get("token", "").encode()
    board.event(sim_link.EVENT_LOG, token)
    rx = bytearray(4)
    got = board.uart.transact(b"\x01\x02\x03", 3, rx, 4, 500)
    board.uart.write(rx, got)
    if drop_more:
        board._take = _first_only(board._take)
    while not board.ended:
        board.sleep_until(board.ticks_add(board.ticks_us(), CYCLE_US))
        while board.can.any():
            arb_id, data = board.can.recv()
            board.can.send(data, arb_id)
        board.event(sim_link.EVENT_LOG, "switches %d" % board.switch_bits)
    board.close()


def _first_only(take):
    """The broken client's sleep: frames past the first reply are never asked for."""
    def cut(length):
        return take(length) & ~sim_link.FLAG_MORE
    return cut


if __name__ == "__main__":
    # the firmware's own one-line report of a link error
    sys.exit(main.start(lambda: run("--drop-more" in sys.argv)))
