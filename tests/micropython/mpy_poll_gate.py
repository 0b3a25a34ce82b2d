# firmware/hal/poll_gate.py under the real micropython binary: the gate both sides of the
# link pace their polling with (the firmware's HAL runs it there).
import os

from firmware.hal import poll_gate
from tests.micropython.checks import check, done

# PollGate: off at first; on after a look with the two processes' CPU waits under 2 % of the
# wall time; off at a contended look for 1, then 2 looks; off for good if a file fails.
stat = "/tmp/hexhil_mpy_gate_%d" % poll_gate.CHECK_WAITS
now = [0]


def set_wait(ns):
    with open(stat, "w") as f:
        f.write("123 %d 7\n" % ns)


def look(gate, wait_ns, wall_us):
    set_wait(wait_ns)
    now[0] += wall_us
    for _ in range(poll_gate.CHECK_WAITS - 1):
        gate.due()
    return gate.due()


set_wait(0)
gate = poll_gate.PollGate((stat, stat), lambda: now[0])
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
for _ in range(poll_gate.CHECK_WAITS):
    gate.due()
check(not gate.on and gate.delay_ns is None, "a file that reads no more: off for good")
os.remove(stat)
check(not poll_gate.PollGate(("/nonexistent/schedstat",), lambda: 0).due(), "no file: off")
done("poll_gate")
