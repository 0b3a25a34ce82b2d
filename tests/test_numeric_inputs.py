"""Every number given to hexhil is checked for finiteness and its documented physical range:
in the scenario loader (hil/scenario/rules.py's range rules),
on the command line and through the API alike; one line, exit 2, never a traceback."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from fuzz.fuzz_trace import sample_trace
from hexhil.hil import scenario as scenario_mod
from hexhil import Run, cli
from hexhil.replay import replay_can, replay_firmware
from hexhil.trace.reader import Trace
from hexhil.protocol.errors import UserError
from conftest import ROOT

FT = str(ROOT / "scenarios" / "flat-tripod.toml")

# (scenario TOML, a phrase of the one line)
SCENARIOS = [
    ("[gait]\nperiod_s = 1e308\n", "'gait.period_s' must be in [0.1, 60], got 1e+308"),
    ("[gait]\nperiod_s = 0.01\n", "'gait.period_s'"),
    ("[gait]\nstep_length_m = -0.05\n", "'gait.step_length_m' must be in [0, 0.2]"),
    ("[gait]\nstep_height_m = 3.0\n", "'gait.step_height_m'"),
    ("[gait]\ndirection_deg = 1e9\n", "'gait.direction_deg'"),
    ("[gait]\ndistance_m = -1\n", "'gait.distance_m' must be in [0, 1000]"),
    ("[gait]\nmax_obstacle_height_m = -1\n", "'gait.max_obstacle_height_m'"),
    ("[firmware]\nservo_lost_s = -3\n", "'firmware.servo_lost_s'"),
    ("[firmware]\ncycle_hz = 0\n", "'firmware.cycle_hz' must be in (0, 1000]"),
    ("[firmware]\nreads_per_cycle = -1\n", "'firmware.reads_per_cycle'"),
    ("[scenario]\nseed = -1\n", "'scenario.seed' must be an integer from 0 to 4294967295"),
    ("[scenario]\nseed = 4294967296\n", "'scenario.seed' must be an integer from 0"),
    ("[scenario]\nduration_s = 1e308\n", "'scenario.duration_s' must be at most 1e+09 s"),
    ("[faults]\ncan_drop_rate = 1.5\n", "'faults.can_drop_rate'"),
]


@pytest.mark.parametrize("text,want", SCENARIOS)
def test_the_loader_checks_every_number(text: str, want: str) -> None:
    with pytest.raises(UserError, match="^<t>: .*" + re.escape(want)):
        scenario_mod.from_text(text, "<t>")


@pytest.fixture(scope="module")
def trace(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("num") / "good.mcap"
    sample_trace(path)
    return path


# (argv, a phrase of the one line); T is the trace
CLI = [
    (["run", FT, "--seed", "-1"], "--seed must be an integer from 0 to 4294967295 (2**32 - 1), got -1"),
    (["run", FT, "--seed", str(2**70)], "--seed must be an integer from 0 to 4294967295"),
    (["run", FT, "--duration", "nan"], "--duration must be positive, got nan"),
    (["run", FT, "--duration", "inf"], "--duration must be at most 1e+09 s"),
    (["trace", "cat", "T", "--start", "nan"], "--start must be in [0, 1e+09], got nan"),
    (["trace", "cat", "T", "--end=-inf"], "--end must be in [0, 1e+09], got -inf"),
    (["trace", "export", "T", "x.csv", "--start", "10", "--end", "5"],
     "--start 10 s is not before --end 5 s: the range is empty"),
    (["replay", "T", "--start", "10", "--end", "5"],
     "--start 10 s is not before --end 5 s: the range is empty"),
    (["replay", "T", "--rate", "nan"], "--rate (0: as fast as possible) must be in [0, 1e+06], got nan"),
    (["replay", "T", "--rate", "-1"], "--rate (0: as fast as possible) must be in [0, 1e+06]"),
    (["replay", "T", "--can", "virtual:0", "--rate", "inf"], "--rate (0: back to back)"),
    (["bus", "--seed", "-5", "--duration", "0.1"], "--seed must be an integer from 0"),
    (["beams", "run", "--k1", "0.1", "--k2", "0.1", "--strategy", "none", "--seed", "-1"],
     "--seed must be an integer"),
    (["model", "mjcf", "--scenario", FT, "--seed", "-1"], "--seed must be an integer from 0"),
    (["model", "mjcf", "--scenario", FT, "--seed", str(2**32)], "--seed must be an integer"),
    (["grnn", "dataset", "--out", "T.d", "--seed", "-1"], "--seed must be an integer from 0"),
    (["grnn", "dataset", "--out", "T.d", "--seed", str(2**32 - 4), "--terrains", "8"],
     "--seed + --terrains - 1 (the last terrain seed) must be an integer from 0 to 4294967295"),
    (["grnn", "train", "T", "--out", "T.pt", "--seed", str(2**40)],
     "--seed must be an integer from 0 to 4294967295"),
]


@pytest.mark.parametrize("argv,want", CLI, ids=lambda v: " ".join(v) if isinstance(v, list)
                         else None)
def test_the_cli_checks_every_number(argv: list[str], want: str, trace: Path,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main([a.replace("T", str(trace), 1) if a.startswith("T") else a
                     for a in argv]) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert want in lines[0], lines[0]


def test_the_api_checks_every_number(trace: Path) -> None:
    with pytest.raises(UserError, match="seed must be an integer from 0 to 4294967295"):
        Run(FT, seed=-5)
    with pytest.raises(UserError, match="duration_s must be positive, got nan"):
        Run(FT, duration_s=float("nan"))
    with pytest.raises(UserError, match="the range is empty"):
        replay_firmware(trace, start_s=10, end_s=5)
    with pytest.raises(UserError, match=r"^rate \(0: back to back\) must be in \[0, 1e\+06\]"):
        replay_can(trace, "virtual:0", rate=float("nan"))
    with Trace(trace) as t, pytest.raises(UserError, match=r"^start_s must be in \[0, 1e\+09\], got nan"):
        list(t.messages(start_s=float("nan")))
    assert scenario_mod.check_seed(2**32 - 1, "seed") == 2**32 - 1
