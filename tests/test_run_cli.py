"""``hexhil run``: the shipped scenarios end to end, the JSON summary, one-line errors."""
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
HEXHIL = str(Path(sys.executable).with_name("hexhil"))
KEYS = {"scenario", "seed", "firmware_runtime", "sim_time_s", "wall_time_s", "real_time_factor",
        "cycles", "overruns", "unhandled_exceptions", "serial_digest", "faults",
        "stopped_safely", "stop_reason", "body", "trace"}


def hexhil(*args):
    return subprocess.run([HEXHIL, *args], cwd=ROOT, capture_output=True, text=True, timeout=300)


def summary(r):
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("name,speed", [("flat-tripod", 0.036), ("flat-wave", 0.013)])
def test_flat_scenarios_30_s_under_micropython(name, speed):
    s = summary(hexhil("run", f"scenarios/{name}.toml", "--json"))
    assert KEYS <= set(s)
    assert s["firmware_runtime"] == "micropython" and s["sim_time_s"] == 30.0
    assert s["unhandled_exceptions"] == 0 and s["overruns"] == 0 and s["cycles"] == 1500
    assert s["stopped_safely"] is False and s["stop_reason"] is None and s["trace"] is None
    # ground truth from the MuJoCo world: the paper's speed (Sec. 3.3) within 15 %
    assert s["body"]["dx_m"] == pytest.approx(speed * 30.0, rel=0.15)
    # ... and the distance the firmware itself commanded (dead reckoning at nominal speed)
    assert s["commanded_distance_m"] == pytest.approx(speed * 30.0, rel=0.01)
    assert s["body"]["dx_m"] == pytest.approx(s["commanded_distance_m"], rel=0.15)
    assert abs(s["body"]["dy_m"]) < 0.1 * s["body"]["dx_m"]


def test_faults_scenario_and_digest_repeats():
    a = summary(hexhil("run", "scenarios/faults.toml", "--json"))
    b = summary(hexhil("run", "scenarios/faults.toml", "--json", "--python", "cpython"))
    assert a["serial_digest"] == b["serial_digest"]
    assert a["overruns"] == 0 and a["cycles"] == 1500
    assert a["faults"]["unplug"] == 2 and a["faults"]["bit_error"] > 0
    assert a["stopped_safely"] is True
    assert a["stop_reason"].startswith("servo 14 ")
    c = summary(hexhil("run", "scenarios/faults.toml", "--json", "--seed", "8", "--duration", "4"))
    assert c["seed"] == 8 and c["sim_time_s"] == 4.0 and c["stopped_safely"] is False


@pytest.mark.parametrize("body,needle", [
    ("[gait]\nspeed = 1\n", "unknown key 'gait.speed'"),
    ("[firmware]\ncycle_hz = 'fast'\n", "'firmware.cycle_hz' must be a number"),
    ("[gait]\nname = 'gallop'\n", "'gait.name' must be tripod or wave"),
])
def test_scenario_errors_are_one_line_exit_2(tmp_path, body, needle):
    p = tmp_path / "bad.toml"
    p.write_text(body)
    r = hexhil("run", str(p))
    assert r.returncode == 2
    assert needle in r.stderr and str(p) in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr


def test_missing_file_and_bad_flag():
    r = hexhil("run", "scenarios/nope.toml")
    assert r.returncode == 2 and "not found" in r.stderr and "nope.toml" in r.stderr
    r = hexhil("run", "scenarios/faults.toml", "--duration", "-1")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
