"""What a timed fault puts in place while it lasts (hil/servobus/faults.py starts and ends
them): a servo's Present Position stuck or noisy, a leg's switch pressed during its swing."""
from __future__ import annotations

import random
from typing import Callable

from hexhil.hil.scenario.faults_section import FaultEntry


class SwingPress:
    """A press during the swing: once the leg's foot has carried no load for ``after_s``
    (at the instants the switches are read: the firmware's samples), its switch reads
    pressed for ``press_s``, once a swing; the foot's next landing arms it again."""

    def __init__(self, e: FaultEntry) -> None:
        self.e = e
        self.lifted_us: int | None = None      # when the foot was first seen unloaded
        self.until_us = -1                     # the press lasts to here
        self.fired = False                     # this swing's press was made

    def pressed(self, t_us: int, loaded: bool, report: Callable[[int, str, str], None]
                ) -> bool:
        if loaded:
            self.lifted_us, self.fired = None, False
        elif self.lifted_us is None:
            self.lifted_us = t_us
        if (not self.fired and self.lifted_us is not None
                and t_us - self.lifted_us >= int(round(self.e.after_s * 1e6))):
            self.fired, self.until_us = True, t_us + int(round(self.e.press_s * 1e6))
            report(t_us, "swing_press", f"leg {self.e.leg}: pressed {self.e.press_s:g} s, "
                   f"{(t_us - self.lifted_us) * 1e-6:.3f} s into its swing")
        return t_us < self.until_us


class StuckReading:
    """Present Position frozen at what it read when the fault began."""

    def __init__(self) -> None:
        self.units: int | None = None

    def apply(self, units: int) -> int:
        if self.units is None:
            self.units = units
        return self.units


class NoisyReading:
    """Present Position plus Gaussian noise of ``sigma`` units, from a seeded stream."""

    def __init__(self, sigma: float, rng: random.Random) -> None:
        self.sigma, self.rng = sigma, rng

    def apply(self, units: int) -> int:
        return int(round(units + self.rng.gauss(0.0, self.sigma)))
