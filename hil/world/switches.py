"""Tibia limit switches (seed 003, Sec. 2.3): a plate on the front of each tibia.

The plate is a real collision geom, so an obstacle pushes on it and on the leg; a MuJoCo
touch sensor sums the normal force on the plate and the switch closes when that force
crosses ``on_n`` and opens again below ``off_n`` (hysteresis: a lever switch's operating
and release forces differ). The level is what the firmware reads on its GPIO pin.
"""
from __future__ import annotations

import numpy as np

SWITCH_ON_N = 0.6    # operating force of a small lever micro-switch through the plate
SWITCH_OFF_N = 0.25  # release force


class SwitchBank:
    """Six switches with hysteresis, updated from the plates' touch-sensor forces.

    Runs every physics step on six floats, so in Python lists: numpy's element-wise
    operations cost 13 us a step while a switch was held, the loop under 1."""

    def __init__(self, n: int = 6, on_n: float = SWITCH_ON_N, off_n: float = SWITCH_OFF_N) -> None:
        if not 0 <= off_n < on_n:
            raise ValueError(f"need 0 <= off_n < on_n, got off {off_n} on {on_n}")
        self.on_n = on_n
        self.off_n = off_n
        self.closed = [False] * n
        self.presses = [0] * n  # rising edges so far, per leg
        self._any_closed = False

    def update(self, force_n: np.ndarray) -> bool:
        """Apply one force sample per switch; True when any level changed."""
        force = force_n.tolist()
        on = self.on_n
        if not self._any_closed and max(force) <= on:
            return False  # the usual physics step: all open, none pressed hard enough
        off, closed, changed = self.off_n, self.closed, False
        for i, f in enumerate(force):
            if closed[i]:
                if f < off:
                    closed[i], changed = False, True
            elif f > on:
                closed[i], changed = True, True
                self.presses[i] += 1
        if changed:
            self._any_closed = True in closed
        return changed

    def levels(self) -> list[bool]:
        return list(self.closed)   # asked at every link request; the caller's own copy

    def state(self) -> tuple:
        """All ``update`` changes, for ``set_state`` (the world's checkpoint)."""
        return list(self.closed), list(self.presses), self._any_closed

    def set_state(self, state: tuple) -> None:
        closed, presses, self._any_closed = state
        self.closed[:] = closed
        self.presses[:] = presses
