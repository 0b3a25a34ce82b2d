"""``hexhil`` with a signal sent to itself at a set virtual time (tests/test_nothing_lost.py).

Usage: python tests/kill_child.py KILL_AT_US SIGNAL FSIZE_LIMIT_BYTES hexhil-args...
The signal goes out from the bus's next master write at or after KILL_AT_US, so the kill
lands at a known simulated moment; a FSIZE limit > 0 makes writes past it fail (full disk).
"""
import os
import resource
import sys

from hil import bus
from host_tools import cli

kill_at_us, signum, fsize = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
if fsize > 0:
    resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))
_write = bus.Bus.master_write


def _hooked(self, data):
    if self.clock.t_us >= kill_at_us:
        bus.Bus.master_write = _write
        os.kill(os.getpid(), signum)
    _write(self, data)


if signum:
    bus.Bus.master_write = _hooked
sys.argv = ["hexhil", *sys.argv[4:]]
sys.exit(cli.main())
