"""What the robot-log tests share (tests/test_robot_logs.py, tests/test_capture_conformance.py):
our firmware's recorded run and its servo line as a sigrok capture, the CLI in process, and
a trace's serial bursts and CAN frames read back."""
from __future__ import annotations

from pathlib import Path

import pytest

import uart_wave
from hexhil.hil import scenario
from hexhil.hil.run.lockstep import Simulator
from hexhil.cli import main
from hexhil.trace import recorder as rec
from hexhil.trace.protobuf import CanFrame, SerialBytes
from hexhil.trace.reader import Trace

from conftest import HEXHIL, ROOT  # noqa: F401  (HEXHIL: re-exported for its test files)
RATE_HZ = 8_000_000
BAUD = 1_000_000


def cli(capsys, *argv: str) -> tuple[int, str, str]:
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


def serial_bursts(path: Path) -> list[tuple[int, str, bytes]]:
    with Trace(path) as tr:
        out = []
        for m in tr.messages(["/serial"]):
            s = SerialBytes.FromString(m.data)
            if s.data:
                out.append((m.log_time_ns // 1000, s.direction, bytes(s.data)))
    return out


def can_frames(path: Path) -> list[tuple[int, str, int, bytes]]:
    with Trace(path) as tr:
        return [(m.log_time_ns // 1000, f.direction, f.arbitration_id, bytes(f.data))
                for m in tr.messages(["/can/raw"]) if (f := CanFrame.FromString(m.data))]


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    """Our firmware (micropython) on 18 emulated AX-12s for 0.5 s, recorded."""
    path = tmp_path_factory.mktemp("robot") / "run.mcap"
    s = {section: {} for section in scenario.SCHEMA}
    with rec.Recorder(path, {"scenario": "defaults", "seed": 0}) as r:
        result = Simulator(s, seed=0, recorder=r).run(duration_s=0.5, python="micropython")
    assert result.exit_code == 0 and result.cycles > 10
    return path


@pytest.fixture(scope="module")
def run_sr(run) -> Path:
    """The run's servo line as a logic analyser sees it: data and direction channels."""
    wave = uart_wave.samples(serial_bursts(run), BAUD, RATE_HZ, direction=True)
    return uart_wave.write_sr(run.with_name("run.sr"), wave, RATE_HZ)


def streams(bursts) -> dict[str, bytes]:
    return {d: b"".join(data for _, who, data in bursts if who == d) for d in ("tx", "rx")}



def refused(capsys, *argv) -> str:
    rc, out, err = cli(capsys, *argv)
    assert rc == 2 and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    return err


