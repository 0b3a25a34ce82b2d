# protocol/sim_link.py under the real micropython binary: the framing constants both
# programs (firmware/hal/sim.py and hil/link/firmware_process.py) agree on.
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

done("sim_link")
