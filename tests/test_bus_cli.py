"""`hexhil bus` configuration: flags over scenario over defaults, one-line errors."""
from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from hexhil.hil import scenario
from hexhil.hil.scenario import FaultEntry, FaultKind
from hexhil.cli.bus import build_bus, parse_ids, register
from hexhil.protocol.errors import UserError
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl


def args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    register(parser.add_subparsers())
    return parser.parse_args(["bus", *argv])


def test_parse_ids():
    assert parse_ids("1-3,7,2") == [1, 2, 3, 7]
    for bad in ("3-1", "x", "250-254"):
        with pytest.raises(UserError):
            parse_ids(bad)


def test_scenario_sets_bus_and_faults_and_flags_win(tmp_path: Path):
    path = tmp_path / "s.toml"
    path.write_text("[scenario]\nseed = 4\n[bus]\nservos = 4\nfirst_id = 10\nbaud = 57142\n"
                    "return_delay_us = 100\nedition = 'original'\n"
                    "[faults]\nunplug = [{id = 11, at_s = 0.001}]\n")
    sc = scenario.load_scenario(path)
    bus, faults = build_bus(args("--pty"), sc)
    assert [s.id for s in bus.servos] == [10, 11, 12, 13] and bus.baud == 57142
    s = bus.servos[0]
    assert s.baud_bps == 57142 and s.return_delay_us == 100 and s.edition == "original"
    bus.master_write(dxl.ping(10))
    assert dxl.Parser().feed(bus.master_read(6, 10_000)) == [dxl.Packet(10, 0, b"", dxl.status(10))]
    bus.idle_until(2000)
    assert faults.counts == {"unplug": 1}
    bus2, _ = build_bus(args("--pty", "--ids", "1,2,11", "--baud", "1000000", "--edition",
                             "emanual", "--stall", "2:0.5"), sc)
    assert [s.id for s in bus2.servos] == [1, 2, 11] and bus2.servos[0].baud_bps == 1_000_000
    assert bus2.faults.config.stall == (FaultEntry(FaultKind.STALL, 0.5, id=2),)
    assert bus2.faults.config.unplug == (FaultEntry(FaultKind.UNPLUG, 0.001, id=11),)


@pytest.mark.parametrize("argv, message", [
    (("--baud", "300000"), "no AX-12 rate"),
    (("--servos", "3", "--ids", "1-2"), "--servos 3 but --ids lists 2"),
    (("--bit-error-rate", "2"), "bit_error_rate must be in"),
    (("--voltage-sag", "5:2:1"), "at_s < until_s"),
])
def test_bad_flags_are_user_errors(argv, message):
    with pytest.raises(UserError, match=message):
        build_bus(args("--pty", *argv), None)


def test_57600_bps_is_served_by_the_nearest_register_within_3_percent():
    bus, _ = build_bus(args("--pty", "--baud", "57600", "--servos", "2"), None)
    assert bus.baud == 57600 and bus.servos[0].baud_bps == 57142  # 0.8 % off: still decodes
    bus.master_write(dxl.read(2, ax12.MODEL_NUMBER_L, 2))
    assert dxl.Parser().feed(bus.master_read(8, 20_000)) == [
        dxl.Packet(2, 0, b"\x0c\x00", dxl.status(2, 0, b"\x0c\x00"))]
    bad = bytearray(dxl.ping(1))
    bad[-1] ^= 0x0F
    bus.master_write(bytes(bad))
    assert dxl.Parser().feed(bus.master_read(6, 20_000))[0].code == dxl.ERR_CHECKSUM


def test_default_is_18_servos_at_1_mbps_emanual():
    bus, faults = build_bus(args("--pty"), None)
    assert [s.id for s in bus.servos] == list(range(1, 19)) and bus.faults is None
    assert all(s.value("temperature_limit") == 70 and s.baud_bps == 1_000_000 for s in bus.servos)
    assert ax12.baud_to_bps(bus.servos[0].table[ax12.BAUD_RATE]) == bus.baud
