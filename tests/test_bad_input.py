"""Bad input, everywhere: every command, option and file type refused with one
line on stderr that names what is wrong and where, exit status 2, never a traceback.

The table runs in-process through ``hexhil.cli.main``; the cases that would serve
forever if a refusal regressed (a busy port) run as a child with a timeout.
"""
from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from fuzz.fuzz_trace import sample_trace
from hexhil import cli
from conftest import ROOT

FT = str(ROOT / "scenarios" / "flat-tripod.toml")
FILES = {
    "badtoml.toml": "[scenario\nname=1\n", "unknown.toml": "[nope]\nx=1\n",
    "wrongtype.toml": '[bus]\nservos="many"\n', "servos0.toml": "[bus]\nservos=0\n",
    "baud.toml": "[bus]\nbaud=123\n", "rd.toml": "[bus]\nreturn_delay_us=3\n",
    "unplug.toml": "[faults]\nunplug=[{id=300, at_s=1.0}]\n",
    "ber.toml": "[faults]\nbit_error_rate=2.0\n", "gait.toml": '[gait]\nname="gallop"\n',
    "sag.toml": "[faults]\nvoltage_sag=[{volts=9.0}]\n", "empty.mcap": "",
    "inf.toml": "[firmware]\ncycle_hz=inf\n", "pyfoo.toml": '[firmware]\npython="foo"\n',
    "longrun.toml": "[scenario]\nduration_s=1e308\n",
    "notmcap.mcap": "hello\n", "bad.csv": "a,b\n1,2\n", "afile": "",
    "notzip.sr": "PK not really\n", "robot.xyz": "", "badmap.toml": "[serail]\nbaud=1\n",
    "deep.toml": "a = " + "[" * 5000 + "]" * 5000 + "\n", "empty.toml": "",
    "exists.png": "", "unplug99.toml": "[faults]\nunplug=[{id=99, at_s=1.0}]\n",
    "leg.toml": '[faults]\nswitch_stuck=[{leg="XX", pressed=true, at_s=1.0}]\n',
}
SIGNAL = ('[case]\nscenario = "' + FT + '"\nduration_s = 2\n[[expect]]\nname = "x"\n'
          'kind = "signal"\nstat = "max"\nlimit = [0, 70]\n')
FILES.update({
    "typo.toml": SIGNAL + 'topic = "/servos"\nfield = "servos[0].temprature_c"\n',
    "notopic.toml": SIGNAL + 'topic = "/servo"\nfield = "servos[0].temperature_c"\n',
    "index.toml": SIGNAL + 'topic = "/servos"\nfield = "servos[18].temperature_c"\n',
    "late.toml": SIGNAL + 'topic = "/servos"\nfield = "servos[0].temperature_c"\n'
                          'window_s = [5, 6]\n',
    "canfield.toml": SIGNAL + 'topic = "/can/heartbeat"\nfield = "stat"\n',
})
WALK = str(ROOT / "examples" / "margin-walk.toml")
CASE = str(ROOT / "tests" / "firmware" / "flat-tripod.toml")
B = "{B}"  # the case's folder, filled in by the fixture

# (argv, a phrase the one line must hold)
CASES = [
    (["nonsense"], "invalid choice: 'nonsense'"),
    (["--bogus"], "unrecognized arguments: --bogus"),
    (["protocol", "decode", "zz"], "not hex: 'z'"),
    (["protocol", "decode", "--status", "--instruction", "FF"], "--instruction: not allowed"),
    (["run", f"{B}/missing.toml"], "missing.toml: scenario file not found"),
    (["run", B], "cannot read scenario (IsADirectoryError)"),
    (["run", f"{B}/badtoml.toml"], "badtoml.toml: not valid TOML"),
    (["run", f"{B}/unknown.toml"], "unknown section '[nope]'"),
    (["run", f"{B}/wrongtype.toml"], "'bus.servos' must be an integer"),
    (["run", f"{B}/servos0.toml"], "servos 0 from ID 1 do not fit"),
    (["run", f"{B}/baud.toml"], "baud 123: no AX-12 rate"),
    (["run", f"{B}/rd.toml"], "'bus.return_delay_us' must be even"),
    (["run", f"{B}/unplug.toml"], "'unplug' servo id must be 0-253, got 300"),
    (["run", f"{B}/ber.toml"], "bit_error_rate must be in [0, 1), got 2.0"),
    (["run", f"{B}/gait.toml"], "'gait.name' must be tripod or wave"),
    (["run", f"{B}/sag.toml"], "key 'voltage_sag.at_s' is required in a 'voltage_sag' entry"),
    (["run", f"{B}/inf.toml"], "'firmware.cycle_hz' must be a finite number, got inf"),
    (["run", FT, "--duration", "-1"], "--duration must be positive"),
    (["run", FT, "--duration", "abc"], "--duration: invalid float value"),
    (["run", FT, "--duration", "nan"], "--duration must be positive, got nan"),
    (["run", FT, "--duration", "inf"], "--duration must be at most 1e+09 s"),
    (["run", FT, "--duration", "1e308"], "--duration must be at most 1e+09 s"),
    (["run", f"{B}/longrun.toml"], "key 'scenario.duration_s' must be at most 1e+09 s"),
    (["run", f"{B}/pyfoo.toml"], "pyfoo.toml: key 'firmware.python' must be one of "
     "micropython, cpython, cpython-inprocess, got 'foo'"),
    (["run", FT, "--python", "jython"], "--python: invalid choice"),
    (["run", FT, "--seed", "x"], "--seed: invalid int value"),
    (["run", FT, "--out", f"{B}/nodir/x.mcap"], "x.mcap: cannot write trace"),
    (["run", FT, "--can-server", "99999"], "--can-server 99999: port must be 0-65535"),
    (["run", FT, "--can-server", "0", "--can-wait", "-1"], "--can-wait must be 0 or more"),
    (["bus", "--duration", "inf"], "--duration must be at most 1e+09 s"),
    (["bus", "--ids", "5-1"], "--ids '5-1': IDs must be 0-253, low before high"),
    (["bus", "--ids", "a"], "--ids 'a': expected IDs like"),
    (["bus", "--ids", "1-300"], "--ids '1-300'"),
    (["bus", "--servos", "0"], "servos 0 from ID 1 do not fit"),
    (["bus", "--baud", "0"], "'bus.baud' must be positive"),
    (["bus", "--tcp", "70000"], "--tcp 70000: port must be 0-65535"),
    (["bus", "--unplug", "x"], "--unplug 'x': expected numbers"),
    (["bus", "--bit-error-rate", "1.5"], "bit_error_rate must be in [0, 1), got 1.5"),
    (["bus", "--scenario", f"{B}/missing.toml"], "missing.toml: scenario file not found"),
    (["conformance", "--port", f"{B}/nodev"], "cannot open"),
    (["conformance", "--port", "x", "--ids", "1-999"], "--ids '1-999'"),
    (["conformance", "--port", "socket://127.0.0.1:1"], "Connection refused"),
    (["trace", "info", f"{B}/missing.mcap"], "missing.mcap: no such trace file"),
    (["trace", "info", f"{B}/empty.mcap"], "not an MCAP file (empty file)"),
    (["trace", "info", f"{B}/notmcap.mcap"], "not an MCAP file (no MCAP magic"),
    (["trace", "info", f"{B}/trunc.mcap"], "trunc.mcap: truncated or corrupt MCAP"),
    (["trace", "cat", f"{B}/good.mcap", "--topics", "/nope"], "no topic matches /nope"),
    (["trace", "cat", f"{B}/good.mcap", "--start", "5", "--end", "1"], "--start 5 s is not before --end 1 s: the range is empty"),
    (["trace", "cat", f"{B}/good.mcap", "--limit", "-1"], "--limit must be 0"),
    (["trace", "export", f"{B}/good.mcap", f"{B}/out.xyz"], "unknown export format '.xyz'"),
    (["trace", "export", f"{B}/good.mcap", f"{B}/afile/x"], "cannot create export directory"),
    (["trace", "export", f"{B}/good.mcap", f"{B}/x.csv", "--topics", "/n*"], "no topic matches"),
    (["trace", "recover", f"{B}/missing.mcap", f"{B}/r.mcap"], "no such trace file"),
    (["trace", "recover", f"{B}/good.mcap", f"{B}/good.mcap"], "needs a different output"),
    (["trace", "import-csv", f"{B}/missing.csv", f"{B}/o.mcap"], "no such CSV file"),
    (["trace", "import-csv", f"{B}/bad.csv", f"{B}/o.mcap"], "CSV lacks column(s)"),
    (["trace", "import-csv", f"{B}/bin.csv", f"{B}/o.mcap"], "not a readable CSV"),
    (["trace", "import", f"{B}/missing.sr", "--out", f"{B}/o.mcap"], "no such log file"),
    (["trace", "import", f"{B}/notzip.sr", "--out", f"{B}/o.mcap"], "not a sigrok session"),
    (["trace", "import", f"{B}/robot.xyz", "--out", f"{B}/o.mcap"], "give --as can"),
    (["trace", "import", f"{B}/notzip.sr", "--map", f"{B}/badmap.toml", "--out",
      f"{B}/o.mcap"], "unknown map section(s) serail"),
    (["trace", "import", f"{B}/notmcap.mcap", "--as", "can", "--out", f"{B}/o.mcap"],
     "not a CAN log python-can reads"),
    (["conformance", "--capture", f"{B}/notzip.sr"], "not a sigrok session"),
    (["conformance", "--capture", f"{B}/empty.mcap"], "not an MCAP file"),
    (["conformance", "--capture", f"{B}/notzip.sr", "--port", "x"], "one of them"),
    (["replay", f"{B}/notmcap.mcap"], "not an MCAP file"),
    (["replay", f"{B}/good.mcap", "--rate", "-1"], "--rate (0: as fast as possible) must be in [0, 1e+06], got -1.0"),
    (["replay", f"{B}/good.mcap", "--can", "bogus"], "--can wants INTERFACE:CHANNEL"),
    (["estimate", f"{B}/good.mcap"], "no force frames"),
    (["beams", "estimate", "--k1", "-1", "--k2", "0.1", "--hb-mm", "0", "--noise", "0",
      "--unknowns", "4"], "k1"),
    (["beams", "run", "--k1", "0.1", "--k2", "0.1", "--strategy", "fly"], "--strategy"),
    (["experiment", "tactile-hexapod", "--workers", "0"], "--workers must be at least 1"),
    (["experiment", "tactile-hexapod", "--scheduler", "tcp://127.0.0.1:abc"],
     "the port is not a number"),
    (["fuzz", FT, "--expect", str(ROOT / "examples" / "fuzz-flat-tripod.toml"), "--scheduler",
      "tcp://127.0.0.1:abc"], "the port is not a number"),
    (["experiment", "tactile-hexapod", "--seeds", "-1"], "--seeds must be 1-1000, got -1"),
    (["experiment", "force-sensing", "--seeds", "0"], "--seeds must be 1-1000, got 0"),
    (["experiment", "tactile-hexapod", "--out", f"{B}/afile"], "exists and is not a folder"),
    (["run", f"{B}/fifo.toml"], "fifo.toml: not a regular file"),
    (["run", "/dev/null"], "/dev/null: not a regular file"),
    (["run", f"{B}/empty.toml"], "empty.toml: an empty scenario"),
    (["run", f"{B}/deep.toml"], "deep.toml: not valid TOML: arrays or tables nested too deeply"),
    (["test", f"{B}/deep.toml"], "deep.toml: not valid TOML: arrays or tables nested too deeply"),
    (["bus", "--scenario", f"{B}/deep.toml"], "nested too deeply"),
    (["run", f"{B}/unplug99.toml"], "'unplug' names servo 99, and the bus has IDs 1-18"),
    (["bus", "--ids", "1-18", "--unplug", "99:1"], "'unplug' names servo 99"),
    (["run", f"{B}/leg.toml"], "'switch_stuck.leg' must be 0-5 or one of LF, LM, LH, RF, RM, "
     "RH, got 'XX'"),
    (["conformance", "--port", "x", "--ids", "1", "--timeout-ms", "nan"],
     "--timeout-ms and --scan-timeout-ms must be positive and finite"),
    (["conformance", "--port", "x", "--ids", "1", "--scan-timeout-ms", "inf"],
     "must be positive and finite"),
    (["render", f"{B}/good.mcap", "--out", f"{B}/r.gif", "--fps", "100000"],
     "--fps 100000: a video has more than 0 and at most 100 frames a second"),
    (["render", f"{B}/good.mcap", "--out", f"{B}/r.gif", "--fps", "nan"], "--fps nan"),
    (["render", f"{B}/good.mcap", "--out", f"{B}/r.mp4", "--width", "100000"],
     "each side is 16-4096 pixels"),
    (["render", f"{B}/good.mcap", "--out", f"{B}/missing/r.png"], "no such directory"),
    (["render", f"{B}/good.mcap", "--out", f"{B}/adir.png"], "adir.png: is a directory"),
    (["render", f"{B}/good.mcap", "--out", f"{B}/exists.png"],
     "exists.png exists: pass --overwrite to replace it"),
    (["margin", FT, "--expect", WALK, "--png", f"{B}/missing/m.png"], "no such directory"),
    (["margin", "scenarios/beams-flimsy.toml", "--expect", WALK], "runs the hexapod firmware"),
    (["test", CASE, "--junit", f"{B}/missing/r.xml"], "--junit", ),
    (["test", CASE, "--junit", B], "is a directory"),
    (["replay", f"{B}/good.mcap", "--can", "virtual:x", "--start", "1000"],
     "no CAN frames in the chosen time range"),
    (["trace", "info", f"{B}/fifo.mcap"], "fifo.mcap: not a regular file"),
    (["replay", f"{B}/fifo.mcap"], "fifo.mcap: not a regular file"),
    (["trace", "import-csv", f"{B}/fifo.mcap", f"{B}/o2.mcap"], "not a regular file"),
    (["experiment", "tactile-hexapod", "--seeds", "100000000"], "--seeds must be 1-1000"),
    (["run", FT, "--can-wait", "3"], "--can-wait waits for clients of --can-server"),
    (["test", f"{B}/typo.toml"], "no field 'temprature_c' in /servos's messages"),
    (["test", f"{B}/notopic.toml"], "key 'topic': no topic '/servo' in a trace"),
    (["test", f"{B}/index.toml"], "servos[18] is out of range (the bus has 18 servos: 0-17)"),
    (["test", f"{B}/late.toml"], "key 'window_s' [5, 6] reaches past the run's end (2 s)"),
    (["test", f"{B}/canfield.toml"], "frame heartbeat has no signal 'stat'"),
]


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("bad")
    for name, text in FILES.items():
        (d / name).write_text(text)
    (d / "bin.csv").write_bytes(bytes(range(128, 256)) * 3)
    os.mkfifo(d / "fifo.toml")        # would block a read for ever
    os.mkfifo(d / "fifo.mcap")
    (d / "adir.png").mkdir()
    good = sample_trace(d / "good.mcap")
    (d / "trunc.mcap").write_bytes(good[:len(good) // 2])
    return d


def _one_line(err: str, want: str) -> None:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("hexhil: ") and want in lines[0], lines[0]
    assert "Traceback" not in err


def test_the_table_has_forty_cases_or_more() -> None:
    assert len(CASES) >= 40


@pytest.mark.parametrize("argv,want", CASES, ids=lambda v: " ".join(v) if isinstance(v, list)
                         else None)
def test_bad_input_gets_one_line_and_status_2(argv: list[str], want: str, folder: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    argv = [a.replace(B, str(folder)) for a in argv]
    assert cli.main(argv) == 2
    _one_line(capsys.readouterr().err, want)


@pytest.mark.parametrize("command", [["bus", "--tcp", "{port}"],
                                     ["run", FT, "--duration", "0.1", "--can-server", "{port}"]])
def test_a_busy_port_gets_one_line_and_status_2(command: list[str]) -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = str(s.getsockname()[1])
        argv = [a.replace("{port}", port) for a in command]
        proc = subprocess.run([sys.executable, "-m", "hexhil.cli", *argv], cwd=ROOT,
                              capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    _one_line(proc.stderr, port)
