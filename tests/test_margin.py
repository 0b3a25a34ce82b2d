"""``hexhil margin``: the bus hooks it sweeps (off by default, so every shipped run keeps its
bytes) and a small sweep that finds the firmware's reply budget: a reply later than
TIMEOUT_MARGIN_US (100 us, firmware/servo_bus/v1.py) after its wire time is a time-out."""
from __future__ import annotations

import dataclasses
from pathlib import Path

from hexhil.firmware.servo_bus.v1 import TIMEOUT_MARGIN_US
from hexhil.hil.servobus.line import Bus
from hexhil.hil.clock import VirtualClock
from hexhil.hil.servobus.ax12_servo import Servo
from hexhil.expect import margin_sweep, spec
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl
from conftest import ROOT


def _bus() -> Bus:
    s = Servo(1)
    s.table[ax12.RETURN_DELAY_TIME] = 0
    return Bus([s], VirtualClock())


def test_latency_and_held_return_delay_delay_what_the_master_hears() -> None:
    ping = dxl.ping(1)
    arrival = {}
    for name, setup in (("plain", lambda b: None),
                        ("latency", lambda b: setattr(b, "rx_latency_us", 300)),
                        ("delay", lambda b: setattr(b, "return_delay_override_us", 200))):
        bus = _bus()
        setup(bus)
        bus.master_write(ping)
        t0 = bus.clock.t_us
        assert len(bus.master_read(6, 10_000)) == 6
        arrival[name] = bus.clock.t_us - t0
    assert arrival["latency"] - arrival["plain"] == 300
    assert arrival["delay"] - arrival["plain"] == 200


def test_a_master_off_the_servos_baud_is_heard_by_its_own_timing() -> None:
    bus = _bus()
    bus.set_master_baud(1_100_000)   # 10 % fast: the servo cannot decode the ping
    bus.master_write(dxl.ping(1))
    assert bus.master_read(6, 10_000) == b""


def test_the_sweep_finds_the_firmwares_reply_budget(tmp_path: Path) -> None:
    case = spec.load(ROOT / "tests" / "firmware" / "flat-tripod.toml")
    case = dataclasses.replace(case, duration_s=6.0, expectations=(spec.expectation(
        "test", {"name": "walks", "kind": "displacement", "window_s": [1, 6], "dx_m": [0.1, 1]}),))
    m = margin_sweep.sweep(case, "cpython-inprocess",
                     axes={"return_delay_us": (0, TIMEOUT_MARGIN_US, TIMEOUT_MARGIN_US + 20),
                           "adapter_latency_us": (TIMEOUT_MARGIN_US, 1000)},
                     grid=((0,), (0,)), workers=2)
    assert m.first_failing() == {"return_delay_us": TIMEOUT_MARGIN_US + 20,
                                 "adapter_latency_us": 1000}
    assert m.grid[0].holds
    margin_sweep.heat_map(m, str(tmp_path / "m.png"), "test")
    assert (tmp_path / "m.png").stat().st_size > 1000


def test_the_heat_map_has_a_colour_bar_and_only_all_holding_is_green(tmp_path):
    """80 % (one expectation of five failing) must not look like a pass."""
    import matplotlib.pyplot as plt

    cmap, norm = margin_sweep.share_colouring()
    green = cmap(norm(1.0))
    assert all(cmap(norm(s)) != green for s in (0.0, 0.5, 0.8, 0.99))

    def point(name, v, passed):
        return margin_sweep.Point(((name, v),), passed, 5, (), ())

    grid = [point("g", i, p) for i, p in enumerate((5, 4, 2, 0))]
    m = margin_sweep.Margin({"baud_error_pct": [point("baud_error_pct", v, p) for v, p in
                                          ((-6, 3), (0, 5), (6, 4))]}, grid,
                      ((0, 40), (100, 1000)))
    figures = []
    real_close = plt.close
    plt.close = lambda fig=None: figures.append(fig)
    try:
        margin_sweep.heat_map(m, str(tmp_path / "m.png"), "synthetic")
    finally:
        plt.close = real_close
    labels = [ax.get_ylabel() for ax in figures[0].axes]
    assert "expectations holding" in labels   # the colour bar's axis
    real_close(figures[0])


def test_margin_says_whether_the_expectations_hold_at_nominal_timing() -> None:
    from hexhil.expect.margin_sweep import Margin, Point

    def point(axis: str, v: float, holds: bool) -> Point:
        return Point(((axis, v),), 2 if holds else 1, 2, () if holds else ("x",), ())

    far_fails = Margin({"return_delay_us": [point("return_delay_us", 0, True),
                                            point("return_delay_us", 500, False)]}, [], ((), ()))
    all_fail = Margin({"return_delay_us": [point("return_delay_us", 0, False),
                                           point("return_delay_us", 500, False)]}, [], ((), ()))
    assert far_fails.nominal_holds() and not all_fail.nominal_holds()
