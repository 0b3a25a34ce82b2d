"""``hexhil`` with a signal sent to itself at a set virtual time (tests/test_nothing_lost*.py).

Usage: python tests/kill_child.py KILL_AT_US SIGNAL FSIZE_LIMIT_BYTES hexhil-args...
The signal goes out from the bus's next master write at or after KILL_AT_US (through
``Bus.master_write``, or a SYNC_WRITE the compiled reads carry out with the R after it), so
the kill lands at a known simulated moment; a FSIZE limit > 0 makes writes past it fail (full disk).
With KILL_IN_RECORDING=N in the environment the signal waits for the N-th trace opened (an
experiment's N-th run, each on a bus whose clock starts at 0), and each trace's path goes
to stderr as ``recording PATH`` when it opens. With KILL_ON=clock the signal goes out when
the run's virtual clock first reaches KILL_AT_US instead: a world with no servo bus (beams).
"""
import os
import resource
import sys

from hexhil.hil.clock import VirtualClock
from hexhil.hil.servobus import line as bus
from hexhil.hil.servobus.status_reads import StatusReads
from hexhil import cli
from hexhil.trace import recorder

kill_at_us, signum, fsize = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
in_recording = int(os.environ.get("KILL_IN_RECORDING", "0"))
if fsize > 0:
    resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))
_write = bus.Bus.master_write
_carry_out = StatusReads.carry_out
_open = recorder.Recorder.__init__
opened = []


def _fire(line) -> None:
    if line.clock.t_us >= kill_at_us and len(opened) >= in_recording:
        bus.Bus.master_write, StatusReads.carry_out = _write, _carry_out
        os.kill(os.getpid(), signum)


def _hooked(self, data):
    _fire(self)
    _write(self, data)


def _hooked_reads(self, payload, byte_us, write=None):
    if write is not None:
        _fire(self.bus)
    return _carry_out(self, payload, byte_us, write)


def _opening(self, path, *args, **kwargs):
    opened.append(path)
    sys.stderr.write(f"recording {path}\n")
    sys.stderr.flush()
    _open(self, path, *args, **kwargs)


_advance = VirtualClock.advance_to


def _ticking(self, t_us):
    _advance(self, t_us)
    if t_us >= kill_at_us:
        VirtualClock.advance_to = _advance
        os.kill(os.getpid(), signum)


if signum and os.environ.get("KILL_ON") == "clock":
    VirtualClock.advance_to = _ticking
elif signum:
    bus.Bus.master_write, StatusReads.carry_out = _hooked, _hooked_reads
if in_recording:
    recorder.Recorder.__init__ = _opening
sys.argv = ["hexhil", *sys.argv[4:]]
sys.exit(cli.main())
