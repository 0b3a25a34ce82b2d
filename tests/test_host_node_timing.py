"""A host node ticks at its period on the run's clock (docs/api.md ``HostNode``), not on
the firmware's next cycle boundary after it: the driver stops the firmware's sleep at the
node's tick, so a 100 ms node ticks with the trace's 10 Hz ground truth."""

import hexhil as hx
from conftest import ROOT


class Clocked:
    def __init__(self, period_us: int, first_tick_us: int | None = None) -> None:
        self.period_us = period_us
        if first_tick_us is not None:
            self.first_tick_us = first_tick_us
        self.ticks: list[int] = []

    def tick(self, t_us: int) -> None:
        self.ticks.append(t_us)


def _ticks(*nodes: Clocked, duration_s: float = 0.5) -> None:
    scenario = hx.load_scenario(str(ROOT / "scenarios" / "flat-tripod.toml"))
    run = hx.Run(scenario, runtime=hx.Runtime.CPYTHON_INPROCESS, duration_s=duration_s)
    for node in nodes:
        run.add_node(node)
    run.run()


def test_a_node_ticks_at_its_period_and_its_first_tick():
    every_100, from_250, odd = Clocked(100_000), Clocked(100_000, 250_000), Clocked(33_000)
    _ticks(every_100, from_250, odd)
    assert every_100.ticks[:4] == [100_000, 200_000, 300_000, 400_000]
    assert from_250.ticks[:3] == [250_000, 350_000, 450_000]
    assert odd.ticks[:5] == [33_000, 66_000, 99_000, 132_000, 165_000]


def test_node_ticks_are_the_same_run_after_run():
    a, b = Clocked(70_000), Clocked(70_000)
    _ticks(a)
    _ticks(b)
    assert a.ticks == b.ticks and len(a.ticks) >= 6
