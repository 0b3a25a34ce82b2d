"""The rough edges a new user hit: exports that cannot be what their name says,
times and stiffnesses outside what a trace or the world holds, and a pacing warning only
when a master can notice. Each refusal is one line on stderr and exit status 2."""
from __future__ import annotations

from pathlib import Path

import pytest

from hexhil.firmware.hal import serial as fw_serial
from fuzz.fuzz_trace import sample_trace
from hexhil import cli
from hexhil.cli import bus as bus_cli


@pytest.fixture(scope="module")
def trace(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("edges") / "good.mcap"
    sample_trace(path)
    return path


def _refused(capsys: pytest.CaptureFixture[str], argv: list[str], want: str) -> str:
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and err.startswith("hexhil: ") and want in err, err
    return err


def test_a_csv_name_in_a_missing_folder_is_refused_and_nothing_is_made(trace, tmp_path, capsys):
    out = tmp_path / "nonexistent" / "dir" / "x.csv"
    _refused(capsys, ["trace", "export", str(trace), str(out), "--topics", "/body"],
             f"folder {out.parent} does not exist")
    assert not (tmp_path / "nonexistent").exists()


def test_a_csv_name_for_many_topics_is_refused_not_made_a_folder(trace, tmp_path, capsys):
    out = tmp_path / "all.csv"
    err = _refused(capsys, ["trace", "export", str(trace), str(out)], "a .csv file holds one topic")
    assert "--topics" in err and "without .csv" in err
    assert not out.exists()
    _refused(capsys, ["trace", "export", str(trace), str(out), "--topics", "/can/*,/body"],
             "holds one topic")
    # one topic: one file; a folder name: one CSV per topic
    assert cli.main(["trace", "export", str(trace), str(out), "--topics", "/body"]) == 0
    assert out.is_file()
    assert cli.main(["trace", "export", str(trace), str(tmp_path / "each")]) == 0
    assert len(list((tmp_path / "each").glob("*.csv"))) > 1


@pytest.mark.parametrize("action", [
    ["run", "--strategy", "interact"], ["plan"],
    ["estimate", "--hb-mm", "0", "--noise", "0", "--unknowns", "2"]])
@pytest.mark.parametrize("k1", ["1e300", "inf", "100.5", "-0.1"])
def test_a_stiffness_the_world_cannot_integrate_is_refused(action, k1, capsys):
    argv = ["beams", action[0], "--k1", k1, "--k2", "0.1", *action[1:]]
    _refused(capsys, argv, "--k1 must be a stiffness in 0..100 N m/rad")


def test_the_lag_warning_waits_for_a_lag_a_master_can_notice():
    assert bus_cli.lag_warning({"max_lag_ms": 2.3, "late_steps": 40}) is None
    warning = bus_cli.lag_warning({"max_lag_ms": 12.0, "late_steps": 3})
    assert warning is not None and "12.0 ms" in warning and "time out a master" in warning


def test_the_lag_limit_is_half_the_firmware_slack_and_below_the_sdk_timeout():
    from dynamixel_sdk import port_handler

    assert bus_cli.MASTER_LAG_LIMIT_MS == fw_serial.LATENCY_US / 1000 / 2
    assert bus_cli.MASTER_LAG_LIMIT_MS < 2 * port_handler.LATENCY_TIMER + 2.0
