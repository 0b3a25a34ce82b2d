# protocol/sim_link.py under the real micropython binary: the framing constants both
# programs (firmware/hal/sim.py and hil/link/firmware_process.py) agree on.
import os
import struct

from protocol import sim_link
from tests.micropython.checks import check, done

ops = {"H": sim_link.OP_HELLO, "X": sim_link.OP_TRANSACT, "S": sim_link.OP_SLEEP,
       "W": sim_link.OP_WRITE, "C": sim_link.OP_CAN, "E": sim_link.OP_EVENT}
for letter in sorted(ops):
    check(ops[letter] == ord(letter), "op %s is its ASCII letter" % letter)
check(len(set(ops.values())) == len(ops), "ops distinct")
check(sim_link.HEADER_LEN == struct.calcsize("<BH"), "header is op u8 + length u16")
check(sim_link.CAN_RECORD_LEN == struct.calcsize("<HB") + 8, "CAN record: id, dlc, 8 data")
events = [sim_link.EVENT_LOG, sim_link.EVENT_EXCEPTION, sim_link.EVENT_STOP,
          sim_link.EVENT_STATS, sim_link.EVENT_TACTILE, sim_link.EVENT_FAULT]
check(events == list(range(6)), "event kinds 0-5")
check(sim_link.FLAG_END == 1, "end flag is bit 0")
check(sim_link.ENV_PORT == "HEXHIL_LINK_PORT", "port variable")
check(sim_link.ENV_PATH == "HEXHIL_LINK_PATH", "Unix socket variable")
check(sim_link.VERSION == 1, "link version 1")
check(sim_link.OP_MORE == ord("M") and sim_link.OP_MORE not in ops.values(), "op M is new")
check(sim_link.FLAG_MORE == 2, "more flag is bit 1")
check(sim_link.SLEEP_HEAD_LEN + sim_link.MAX_CAN_PER_REPLY * sim_link.CAN_RECORD_LEN
      <= sim_link.MAX_REPLY_LEN < sim_link.SLEEP_HEAD_LEN
      + (sim_link.MAX_CAN_PER_REPLY + 1) * sim_link.CAN_RECORD_LEN, "most frames a reply holds")
check(struct.unpack("<Q", sim_link.ERROR_MARK)[0] == sim_link.ERROR_T_US, "error mark")
check(isinstance(sim_link.LinkError("x"), OSError), "a link error is an OSError")

# PollGate: off at first; on after a look with the two processes' CPU waits under 2 % of the
# wall time; off at a contended look for 1, then 2 looks; off for good if a file fails.
stat = "/tmp/hexhil_mpy_gate_%d" % sim_link.POLL_CHECK_WAITS
now = [0]


def set_wait(ns):
    with open(stat, "w") as f:
        f.write("123 %d 7\n" % ns)


def look(gate, wait_ns, wall_us):
    set_wait(wait_ns)
    now[0] += wall_us
    for _ in range(sim_link.POLL_CHECK_WAITS - 1):
        gate.due()
    return gate.due()


set_wait(0)
gate = sim_link.PollGate((stat, stat), lambda: now[0])
check(not gate.due(), "a gate starts off")
gate.waits = 0
check(look(gate, 1000, 1000), "on after a clean look (2 x 1 us waited in 1 ms)")
check(not look(gate, 20000, 1000), "off at a contended look (2 x 19 us in 1 ms)")
check(look(gate, 20000, 1000), "on again after one look")
check(not look(gate, 40000, 1000), "off again (2 x 20 us in 1 ms)")
check(not look(gate, 40000, 1000), "for two looks now")
check(look(gate, 40000, 1000), "then on")
check(gate.off_next == 4 and look(gate, 40000, 1000) and gate.off_next == 2,
      "a clean look halves the next spell off")
gate.close()   # as if the other side were gone: its file reads no more
for _ in range(sim_link.POLL_CHECK_WAITS):
    gate.due()
check(not gate.on and gate.delay_ns is None, "a file that reads no more: off for good")
os.remove(stat)
check(not sim_link.PollGate(("/nonexistent/schedstat",), lambda: 0).due(), "no file: off")
done("sim_link")
