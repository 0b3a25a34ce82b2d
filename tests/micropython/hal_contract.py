# The HAL contract (firmware/hal/base.py) exercised on one back end, under micropython or
# CPython: `hal_contract.py sim` (the link; HEXHIL_LINK_PORT) or `hal_contract.py serial
# --serial PTY`. Prints one JSON object of what it saw; tests/test_hal_contract.py plays the
# other end and compares. The same calls, in the same order, on every back end.
import json
import sys

from firmware.hal import base

METHODS = ("ticks_us", "ticks_diff", "ticks_add", "sleep_until", "perf_us", "io_us",
           "config", "event", "close")


def make(kind):
    if kind == "sim":
        from firmware.hal.sim import Board
        return Board()
    from firmware.hal.serial import Board
    board = Board()
    board.switch_reader = lambda b: 0x15   # what a sensor node would answer
    return board


def main():
    board = make(sys.argv[1])
    seen = {}
    seen["base"] = isinstance(board, base.Board) and isinstance(board.can, base.CAN)
    seen["methods"] = [m for m in METHODS if callable(getattr(board, m, None))]
    seen["switch_count"] = len(board.switches)
    seen["ended_at_boot"] = board.ended
    seen["config"] = board.config()
    t0 = board.ticks_us()
    seen["ticks_add_diff"] = board.ticks_diff(board.ticks_add(t0, 1000), t0)
    rx = bytearray(4)
    got = board.uart.transact(b"\x01\x02\x03", 3, rx, 4, 300000)  # a loaded host answers late
    seen["transact"] = list(rx[:got])
    board.uart.write(b"\x05\x06\x07", 2)
    board.can.send(b"\x11\x22", 0x123)
    board.event(0, "contract")
    seen["can_before_sleep"] = board.can.any()
    wake = board.ticks_add(board.ticks_us(), 20000)
    board.sleep_until(wake)
    seen["woke_late_us"] = board.ticks_diff(board.ticks_us(), wake) >= 0
    seen["switches"] = [s.value() for s in board.switches]
    frames = []
    while board.can.any():
        arb_id, data = board.can.recv()
        frames.append([arb_id, list(data)])
    seen["can_in"] = frames
    seen["can_dropped"] = board.can.dropped
    seen["io_us_ok"] = board.io_us() >= 0 and board.perf_us() >= 0
    board.close()
    print(json.dumps(seen))


main()
