"""A short, seeded slice of every ``make fuzz`` target, so a regression fails ``make test``;
and the inputs the fuzzers found, kept as regression tests with the defect they exposed."""
from __future__ import annotations

import math

import pytest

from fuzz import fuzz_bus, fuzz_can, fuzz_parser, fuzz_scenario, fuzz_trace
from firmware.commands import GaitCommands
from protocol import can_frames as cf

SLICES = {fuzz_parser: 3_000, fuzz_bus: 300, fuzz_can: 3_000, fuzz_scenario: 300,
          fuzz_trace: 25}


@pytest.mark.parametrize("target", SLICES, ids=lambda m: m.__name__.split("_")[-1])
def test_fuzz_slice_finds_nothing(target) -> None:
    for tally in target.run(seed=20, budget_s=None, limit=SLICES[target]):
        assert tally.inputs > 0, tally
        assert tally.escaped == 0, tally.first_escape
        if tally.resync_checked:
            assert tally.resync_found == tally.resync_checked, tally


def test_encode_refuses_a_value_that_is_not_finite() -> None:
    """Found by fuzz_can: infinity escaped as OverflowError, NaN as a bare int() error."""
    for bad in (math.inf, -math.inf, math.nan):
        with pytest.raises(ValueError, match="not a finite number"):
            cf.encode("body_pose", x_m=bad, roll_rad=0.0, pitch_rad=0.0)
        with pytest.raises(ValueError, match="not a finite number"):
            cf.encode("heartbeat", state=0, fault_flags=0, cycle=bad, overruns=0)


class _Ctl:
    """Just enough controller for GaitCommands.apply to act on."""

    def __init__(self) -> None:
        self.calls: list[str] = []
        self.gait = self
        self.rule = self

    def request(self, *a) -> None:
        self.calls.append("gait")

    def set_initial(self, *a) -> None:
        self.calls.append("rule")

    def stop_walking(self) -> None:
        self.calls.append("stop")

    def start_walking(self, *a) -> None:
        self.calls.append("start")


@pytest.mark.parametrize("data", [bytes.fromhex("0105e803e803f401"),   # gait 5
                                  bytes.fromhex("0700e803e803f401")])  # command 7
def test_gait_command_with_an_enum_out_of_range_is_ignored(data: bytes) -> None:
    """Found by fuzz_can: cf.decode passes an enum out of range on, as cantools does, and
    the firmware indexed GAIT_NAMES with it (IndexError in the control loop)."""
    ctl = _Ctl()
    cmd = GaitCommands(0.05)
    cmd.apply(ctl, (cf.ID_GAIT_COMMAND, data), 0)
    assert ctl.calls == [] and cmd.count == 0
