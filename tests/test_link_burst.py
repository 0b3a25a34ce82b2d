"""A burst of 1,000 CAN frames queued for the firmware within one sleep: more
than one sleep reply holds (protocol/sim_link.py MAX_CAN_PER_REPLY), so the host continues
it over OP_MORE replies; every frame must arrive, in order, in that same cycle, under the
real micropython binary and under CPython, and the link stays up."""
import sys

import pytest

from hexhil.hil.run.lockstep import Simulator
from hexhil.hil.scenario import SCHEMA
from hexhil.protocol import can_frames as cf
from hexhil.protocol import sim_link
from mpy import micropython_binary

BURST = 1000
AT_US = 200_000
ECHO = "tests/link_clients/echo_firmware.py"
RUNTIMES = {"micropython": micropython_binary, "cpython": lambda: sys.executable}


def _bare():
    sc = {s: {} for s in SCHEMA}
    sc["_path"] = "<test>"
    return sc


class Burst:
    """A host node that queues ``frames`` at ``AT_US``, in one tick."""

    period_us = 10 ** 9
    first_tick_us = AT_US

    def __init__(self, sim, frames):
        self.sim, self.frames = sim, frames

    def tick(self, t_us):
        for arb_id, data in self.frames:
            self.sim.send_can(arb_id, data)


def test_a_burst_is_more_than_one_reply_holds():
    assert sim_link.MAX_CAN_PER_REPLY < BURST
    assert sim_link.SLEEP_HEAD_LEN + sim_link.MAX_CAN_PER_REPLY * sim_link.CAN_RECORD_LEN \
        <= sim_link.MAX_REPLY_LEN


@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_every_frame_of_a_burst_arrives_in_order(runtime):
    frames = [(0x100 + i % 0x300, i.to_bytes(2, "little") + bytes(i % 7)) for i in range(BURST)]
    sim = Simulator(_bare(), seed=1)
    sim.add_node(Burst(sim, frames))
    heard = sim.can.endpoint("rx")
    r = sim.run(0.5, command=[RUNTIMES[runtime](), ECHO])
    assert r.exit_code == 0, r.stderr_tail
    echoes = [m for m in heard.frames() if m.arbitration_id >= 0x400]
    assert [(m.arbitration_id - 0x400, bytes(m.data)) for m in echoes] == frames
    assert len({m.timestamp for m in echoes}) == 1      # all in the cycle of the burst
    assert r.round_trips >= BURST // sim_link.MAX_CAN_PER_REPLY


@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_the_firmware_takes_every_command_of_a_burst(runtime):
    frames = [cf.encode("heading_command", direction_rad=0.001 * i) for i in range(BURST)]
    sim = Simulator(_bare(), seed=1)
    sim.add_node(Burst(sim, frames))
    r = sim.run(0.5, python=runtime)
    assert r.exit_code == 0 and not r.exceptions, r.stderr_tail
    assert r.firmware.commands == BURST
