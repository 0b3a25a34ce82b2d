"""Virtual time for lockstep runs: integer microseconds, advanced only by the simulator.

Integers keep runs bit-identical across machines; seconds appear only at the edges.
"""


class VirtualClock:
    def __init__(self, t_us: int = 0) -> None:
        self.t_us = int(t_us)

    @property
    def t_s(self) -> float:
        return self.t_us * 1e-6

    def advance_to(self, t_us: int) -> None:
        if t_us < self.t_us:
            raise ValueError(f"virtual time cannot go back ({t_us} < {self.t_us})")
        self.t_us = int(t_us)

    def advance(self, dt_us: int) -> None:
        self.advance_to(self.t_us + int(dt_us))
