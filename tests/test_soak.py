"""The soak scenario's shape and the CAN frame loss it needs (``faults.can_drop_rate``);
the ten-minute soak itself runs in ``make bench`` (bench/bench_soak.py)."""
from __future__ import annotations


import pytest

from hexhil.hil import scenario
from hexhil.hil.canbus.bus import CanBus
from hexhil.hil.clock import VirtualClock
from hexhil.protocol.errors import UserError
from conftest import ROOT


def test_soak_has_every_fault_kind_of_its_scenario() -> None:
    sc = scenario.load_scenario(ROOT / "scenarios" / "soak.toml")
    f = sc.faults
    assert sc.scenario.duration_s == 600
    assert f.bit_error_rate == 1e-4 and f.can_drop_rate == 0.01
    assert f.unplug[0].until_s > f.unplug[0].at_s  # unplugged and replugged
    assert f.voltage_sag and f.overheat


def _bus(rate: float, seed: int) -> tuple[CanBus, list, list]:
    bus = CanBus(VirtualClock(), rate, seed, lambda t, name, detail: faults.append(name))
    faults: list[str] = []
    port = bus.endpoint("rx")
    for i in range(2000):
        bus.send(0x700, bytes(8), direction="tx")
    got = list(port.frames())
    bus.shutdown()
    return bus, got, faults


def test_can_drop_rate_loses_frames_seeded_and_counts_each() -> None:
    a, got_a, faults_a = _bus(0.01, 20)
    b, got_b, _ = _bus(0.01, 20)
    assert 5 <= a.dropped <= 40 and a.dropped == b.dropped
    assert len(got_a) + a.dropped == 2000 and faults_a == ["can_drop"] * a.dropped
    none, got, _ = _bus(0.0, 20)
    assert none.dropped == 0 and len(got) == 2000


@pytest.mark.parametrize("rate", [-0.1, 1.5, float("nan")])
def test_can_drop_rate_outside_0_1_is_refused(rate: float) -> None:
    with pytest.raises(UserError, match="can_drop_rate"):
        scenario.parse({"faults": {"can_drop_rate": rate}})
