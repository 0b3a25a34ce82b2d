"""Whether a side of the simulator link polls for the other's message before it blocks.

The link's contract (protocol/sim_link.py) only carries the hint, ``ENV_SPIN_US`` and the
host's process id; how a side paces its waits is its own. Both sides use this gate: the
firmware's HAL (firmware/hal/sim.py, under MicroPython's unix port and CPython) and the
host's connection (hil/link/firmware_process.py). Linux only: it reads /proc.
"""

CHECK_WAITS = 16   # waits between a gate's looks at the CPU waits
CONTENDED = 0.02   # of the wall time spent waiting for a CPU: the cores are shared
MAX_OFF = 64       # looks polling stays off, at most, after it met contention


def schedstat_paths(peer_pid):
    """This process's and ``peer_pid``'s scheduler statistics, what a gate reads."""
    return ("/proc/self/schedstat", "/proc/%s/schedstat" % peer_pid)


class PollGate:
    """Whether a side polls for the other's message before it blocks (``ENV_SPIN_US``,
    docs/link.md). A poll holds a core, which pays only where each side has one: beside
    other busy processes it takes the core the other side needs. So every
    ``CHECK_WAITS`` waits it reads how long the run's two processes have waited for a
    CPU since its last look (``stat_paths``: their /proc/PID/schedstat, second field, ns).
    Polling starts off; it goes on after a look that found them waiting under
    ``CONTENDED`` of the wall time, and off at a look that found more, then for 1, 2,
    4 ... ``MAX_OFF`` looks (halved again by each clean look while on). Where a file
    cannot be read it stays off. ``now_us``: a microsecond clock. The files stay open (a
    look costs a read each, not an open) until ``close``."""

    def __init__(self, stat_paths, now_us):
        self.now_us = now_us
        self.files = []   # kept open: a look reads them again from the start
        try:
            for path in stat_paths:
                self.files.append(open(path))
        except OSError:
            self.close()
        self.on = False
        self.waits = 0
        self.off_looks = 0   # looks left before polling may go on again
        self.off_next = 1    # how many the next contention while on keeps it off for
        self.t_us = now_us()
        self.delay_ns = self._delay_ns()

    def _delay_ns(self):
        if not self.files:
            return None
        total = 0
        for f in self.files:
            try:
                f.seek(0)
                total += int(f.read().split()[1])
            except (OSError, ValueError, IndexError):
                return None
        return total

    def close(self):
        for f in self.files:
            f.close()
        self.files = []

    def due(self):
        """Whether to poll for this wait (call it only where the message is not in yet: a
        look costs some microseconds)."""
        self.waits += 1
        if self.waits >= CHECK_WAITS and self.delay_ns is not None:
            self.waits = 0
            self._look()
        return self.on

    def _look(self):
        t_us, delay_ns = self.now_us(), self._delay_ns()
        if delay_ns is None:   # the other side is gone
            self.on, self.delay_ns = False, None
            return
        contended = delay_ns - self.delay_ns > CONTENDED * (t_us - self.t_us) * 1000
        self.t_us, self.delay_ns = t_us, delay_ns
        if self.on and contended:
            self.on = False
            self.off_looks = self.off_next
            self.off_next = min(2 * self.off_next, MAX_OFF)
        elif self.on:
            self.off_next = max(1, self.off_next // 2)
        else:
            self.off_looks -= 1
            self.on = self.off_looks <= 0 and not contended
