"""A short, seeded slice of every ``make fuzz`` target, both phases (the seeded generators
and the coverage-guided atheris runs), so a regression fails ``make test``; and the inputs
the fuzzers found, kept as regression tests with the defect they exposed."""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from hexhil.firmware.commands import GaitCommands
from fuzz import (cov, cov_targets, fuzz_bus, fuzz_v2_bus, fuzz_can, fuzz_elf, fuzz_logs,
                  fuzz_parser, fuzz_v2_parser, fuzz_scenario, fuzz_trace)
from hexhil.trace import reader, recover
from hexhil.protocol import can_frames as cf
from hexhil.protocol.dynamixel import v1 as dxl

SLICES = {fuzz_parser: 3_000, fuzz_bus: 300, fuzz_can: 3_000, fuzz_scenario: 300,
          fuzz_trace: 25, fuzz_v2_parser: 3_000, fuzz_v2_bus: 200, fuzz_elf: 500,
          fuzz_logs: 30}


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


# --- the coverage-guided phase (fuzz/cov.py: atheris in a subprocess) -----------------------
COVERAGE_SLICES = {"parser": 2_000, "can": 2_000, "bus": 300, "scenario": 1_000, "trace": 60,
                   "parser2": 1_000, "bus2": 100, "logs": 30}


@pytest.mark.parametrize("name", COVERAGE_SLICES)
def test_coverage_guided_slice_finds_nothing(name: str) -> None:
    """A short seeded atheris run of each target: it ran every input, libFuzzer reported
    the edges it reached beyond the seeds, and nothing crashed."""
    tally = cov.run(name, seed=1, runs=COVERAGE_SLICES[name])
    assert tally.escaped == 0, tally.first_escape
    assert tally.inputs == COVERAGE_SLICES[name], tally
    assert tally.notes["cov"] > 0 and tally.notes["corpus"] > 0, tally.notes
    if name == "parser":
        assert tally.resync_found == tally.resync_checked == tally.inputs


def test_minimise_keeps_the_crash_and_cuts_the_rest() -> None:
    def planted(data: bytes) -> None:
        if b"\xfe" in data and data.count(b"\x01") >= 2:
            raise RuntimeError("planted")
    small, what = cov.minimise(planted, b"abc\x01def\xfe" + bytes(200) + b"\x01zz")
    assert sorted(small) == [1, 1, 0xFE] and what == "RuntimeError: planted"
    assert cov.minimise(planted, b"clean") == (b"clean", "")


def test_a_crash_is_reported_with_its_minimal_input(tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """What libFuzzer leaves behind becomes one row: the minimal input in hex, kept."""
    monkeypatch.setattr(cov, "FINDINGS", tmp_path / "findings")
    artifact = tmp_path / "crash-1234"
    artifact.write_bytes(bytes.fromhex(CAN_OVERFLOW) + b"tail")
    monkeypatch.setattr(cf, "_raw", _overflowing_raw)
    line = cov._finding("can", 77, [artifact], "")
    assert line.startswith(f"can: minimal input ({len(CAN_OVERFLOW) // 2} bytes")
    assert CAN_OVERFLOW in line and "OverflowError" in line
    assert (tmp_path / "findings" / "can-crash.bin").read_bytes().hex() == CAN_OVERFLOW


def _overflowing_raw(frame: str, sig: tuple, value: float) -> int:
    """cf._raw before the fix: a huge value over a small scale overflowed in int()."""
    return int(round(value / sig[2])) if sig[1] == cf.SCALED else int(value)


# Found by the atheris CAN target: body_pose.x_m = 1.3e303 (the frame's doubles) over a
# 1e-4 scale is infinity, and int(round(inf)) raised OverflowError out of cf.encode.
CAN_OVERFLOW = "0100b0001980b000e77f56fffffffffd7e"


def test_encode_clamps_a_huge_finite_value() -> None:
    cov_targets.can_one_input(bytes.fromhex(CAN_OVERFLOW))
    arb_id, data = cf.encode("body_pose", x_m=1e308, roll_rad=-1e308, pitch_rad=0.0)
    assert cf.decode(arb_id, data)[1] == cf.decode(*cf.encode(
        "body_pose", x_m=1e6, roll_rad=-1e6, pitch_rad=0.0))[1]


def test_recover_skips_a_schema_record_with_flipped_bits(tmp_path: Path) -> None:
    """Found by the atheris trace target (a 23 kB input; this is the same defect in a few
    bytes): a cut-off trace whose first schema record, outside any chunk and so under no
    CRC, had a flipped length byte; recover copied it, and its own output did not read.
    Now the damaged copy is skipped and the chunk's good copy used."""
    whole = fuzz_trace.sample_trace(tmp_path / "whole.mcap", seconds=1)
    data = bytearray(whole[:len(whole) // 2])
    at = data.index(b"hexhil/trace.proto") - 3  # the FileDescriptorSet's first length byte
    data[at] ^= 0x40
    cov_targets.trace_one_input(bytes(data))
    src = tmp_path / "damaged.mcap"
    src.write_bytes(bytes(data))
    r = recover.recover(src, tmp_path / "recovered.mcap")
    assert r["messages"] > 0
    with reader.Trace(tmp_path / "recovered.mcap") as t:
        assert sum(1 for _ in t.decoded()) == r["messages"]


def test_parser_drops_a_run_of_garbage_in_one_shift(monkeypatch: pytest.MonkeyPatch) -> None:
    """Found by the atheris parser target (its inputs slowed to 18 ms): a header promising
    240 bytes, then noise with no FF in it. The packet fails its checksum and every noise
    byte was dropped with its own shift of the buffer, n^2 byte moves in one push (on the
    board, a control cycle lost). Now a run up to the next FF goes in one shift."""
    moved = [0]
    drop = dxl.Parser._drop

    def counting(self: dxl.Parser, k: int) -> None:
        moved[0] += self._n - k
        drop(self, k)
    monkeypatch.setattr(dxl.Parser, "_drop", counting)
    data = b"\xff\xff\x01\xf0" + bytes(range(1, 255)) * 2
    cov_targets.parser_one_input(data)
    assert moved[0] < 4 * len(data), moved[0]


def test_a_packet_found_inside_a_rejected_header_is_checked_where_it_lay() -> None:
    """Atheris' Protocol 2.0 parser target, 65 bytes: a valid packet inside a rejected
    header's length is reported with the bytes after it still held; the target (and the
    decoder, tests/test_protocol_decode.py) must read it where it lay, not at the last byte."""
    cov_targets.parser2_one_input(bytes.fromhex(
        "fffffd00fe3a0084fffffd00fffd00000000000000008a840004000101028884fffffffffd00fefffffd"
        "0001030001194e03fffffd0001008a8400040001010272"))
