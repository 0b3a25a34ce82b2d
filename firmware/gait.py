"""The gait clock for seed 003's tripod and wave gaits (Fig. 13), MicroPython-compatible.

A gait (``protocol/hexapod.py`` ``GAITS``) is a period ``T`` in the trajectory's normalised
units (one unit = one leg transfer) and each leg's lift-off phase. Tripod: LM+RF+RH transfer
in the first half of the period, LF+LH+RM in the second (T = 2, duty factor 1/2). Wave: one
leg at a time in the order LF, LM, LH, RF, RM, RH (T = 6, duty factor 5/6). The clock maps
virtual microseconds to normalised time and applies requested changes at a wrap.
"""
from protocol.hexapod import GAITS


class Gait:
    """The gait clock: virtual microseconds to normalised time, changes at wrap only."""

    def __init__(self, name, period_s, t0_us=0):
        self.set(name, period_s)
        self.t0_us = t0_us
        self.pending = None
        self.t = 0.0      # normalised time of the current cycle, 0 <= t < T
        self.wraps = 0    # completed periods

    def set(self, name, period_s):
        if name not in GAITS:
            raise ValueError("unknown gait %r (use tripod or wave)" % name)
        if not period_s > 0:
            raise ValueError("gait period must be positive")
        self.name = name
        self.T, self.phases = GAITS[name]
        self.period_us = int(period_s * 1000000)

    def request(self, name, period_s):
        """Ask for another gait or period; it takes effect when the period wraps."""
        if name not in GAITS:
            raise ValueError("unknown gait %r (use tripod or wave)" % name)
        self.pending = (name, period_s)

    def restart(self, t_us):
        self.t0_us = t_us
        self.t = 0.0

    def advance(self, t_us):
        """Normalised time at virtual time ``t_us``; applies a pending change at a wrap.

        Returns True when a period boundary was crossed since the last call.
        """
        elapsed = t_us - self.t0_us
        wrapped = elapsed >= self.period_us
        if wrapped:
            n = elapsed // self.period_us
            self.wraps += n
            self.t0_us += n * self.period_us
            elapsed -= n * self.period_us
            if self.pending is not None:
                name, period_s = self.pending
                self.pending = None
                self.set(name, period_s)
                self.t0_us = t_us
                elapsed = 0
        self.t = self.T * elapsed / self.period_us
        return wrapped
