"""``hexhil run``: the shipped scenarios end to end, the JSON summary, one-line errors."""
import json
import math

import pytest
from conftest import hexhil_in_process as hexhil

KEYS = {"scenario", "seed", "firmware_runtime", "sim_time_s", "wall_time_s", "real_time_factor",
        "boot_s", "cycles", "overruns", "unhandled_exceptions", "serial_digest", "faults",
        "stopped_safely", "stop_reason", "body", "trace"}


def summary(r):
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("name,speed", [("flat-tripod", 0.036), ("flat-wave", 0.013)])
def test_flat_scenarios_30_s_under_micropython(name, speed):
    s = summary(hexhil("run", f"scenarios/{name}.toml", "--json"))
    assert KEYS <= set(s)
    assert s["firmware_runtime"] == "micropython" and s["sim_time_s"] == 30.0
    assert s["unhandled_exceptions"] == 0 and s["overruns"] == 0
    assert 0.02 < s["boot_s"] < 0.04 and s["cycles"] == math.ceil((30.0 - s["boot_s"]) * 50)
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
    assert a["overruns"] == 0 and a["cycles"] == math.ceil((30.0 - a["boot_s"]) * 50)
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


def test_run_trace_holds_ground_truth_servo_state_and_joints(tmp_path):
    from foxglove_schemas_protobuf.JointStates_pb2 import JointStates

    from hexhil.trace import protobuf as pb
    from hexhil.trace import topics
    from hexhil.trace.reader import open_trace

    out = tmp_path / "t.mcap"
    s = summary(hexhil("run", "scenarios/flat-tripod.toml", "--duration", "1", "--out", str(out),
                       "--json"))
    assert s["trace"] == str(out)
    with open_trace(out) as tr:
        servos = [pb.ServoStates.FromString(m.data) for m in tr.messages([topics.T_SERVOS])]
        joints = [JointStates.FromString(m.data) for m in tr.messages([topics.T_JOINTS])]
        bodies = list(tr.messages([topics.T_BODY]))
    # the first wake (after the boot), then every 100 ms on the grid up to the end, 1.0 s
    assert len(servos) == len(joints) == len(bodies) == 11
    last = servos[-1].servos
    assert [sv.id for sv in last] == list(range(1, 19)) and all(sv.torque_enabled for sv in last)
    names = [j.name for j in joints[-1].joints]
    assert names[:3] == ["LF_coxa", "LF_femur", "LF_tibia"] and len(names) == 18
    # the servo reports the joint it drives: Present Position comes from physics
    for sv, j in zip(last, joints[-1].joints):
        assert abs(sv.position_rad - j.position) < 1e-9
