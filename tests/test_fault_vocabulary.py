"""The named failures: each kind from a scenario's [faults], from the API
(``Run.inject``, a host node) and from ``hexhil bus --inject-stdin``; our firmware's
reaction to each (docs/servo-bus.md, "Fault vocabulary")."""
from __future__ import annotations

import json
import signal
import subprocess
import time

import dynamixel_sdk as sdk
import pytest

from hexhil.hil import scenario as scenario_mod
from hexhil.hil.run.lockstep import Simulator
from hexhil.hil.servobus.faults import Faults
from hexhil.lockstep_run import Run
from hexhil.papers import beam_traversal  # noqa: F401  registers the beams run (docs/api.md)
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.errors import UserError
from test_firmware_loop import scenario
from conftest import HEXHIL, ROOT

RUN_S = 2.0


def run_with(**faults) -> tuple:
    sim = Simulator(scenario(faults=faults), seed=0)
    r = sim.run(RUN_S, python="micropython")
    assert r.unhandled_exceptions == 0, r.exceptions or r.stderr_tail
    return r, sim


def test_brownout_reboots_the_servo_and_our_firmware_walks_on_unaware():
    r, sim = run_with(brownout=[{"id": 5, "at_s": 1.0}])
    assert r.faults["brownout"] == 1
    s5 = sim.core.bus.servo(5)
    assert s5.value("torque_enable") == 0              # rebooted: torque off, RAM defaults
    assert s5.value("return_delay_time") == 0          # EEPROM kept (our firmware wrote 0)
    # our firmware's reaction: none; the leg hangs limp until a restart (docs: a gap)
    assert r.stop_reason is None and r.firmware.state == "walking"


def test_overload_sets_the_bit_and_our_firmware_stops_safely():
    r, sim = run_with(overload=[{"id": 5, "at_s": 1.0}])
    assert r.faults["overload"] == 1
    s5 = sim.core.bus.servo(5)
    assert s5.state_errors() & 0x20 and s5.value("torque_limit") == 0   # Alarm Shutdown 0x24
    assert r.firmware.state == "safe_stop" and "overload" in r.stop_reason


@pytest.mark.parametrize("kind,entry", [
    ("position_stuck", {"id": 5, "at_s": 1.0, "until_s": 1.5}),
    ("position_noise", {"id": 5, "at_s": 1.0, "sigma": 20.0}),
])
def test_position_faults_are_ridden_through(kind, entry):
    r, sim = run_with(**{kind: [entry]})
    assert r.faults[kind] == 1
    # our firmware commands positions open loop and does not read them back to steer
    assert r.stop_reason is None and r.firmware.state == "walking"


def test_position_readings_stuck_and_noisy_are_what_a_master_reads():
    from hexhil.hil.clock import VirtualClock
    from hexhil.hil.servobus.ax12_servo import Servo
    from hexhil.hil.servobus.line import Bus

    servos = [Servo(1), Servo(2)]
    section = {"position_stuck": [{"id": 1, "at_s": 0.0, "until_s": 2.0}],
               "position_noise": [{"id": 2, "at_s": 0.0, "sigma": 5.0}]}
    faults = Faults(scenario_mod.parse({"faults": section}).faults, seed=7)
    bus = Bus(servos, VirtualClock(), faults=faults)
    bus.idle_until(1)
    for s in servos:
        s.handle(0x03, bytes((ax12.TORQUE_ENABLE, 1)), False, 10)
        s.handle(0x03, bytes((ax12.GOAL_POSITION, 0, 3)), False, 10)   # 768
    for s in servos:
        s.advance_to(1_000_000)
    assert servos[0].value("present_position") == 512                # stuck where it was
    noisy = []
    for t in range(2, 12):
        bus.idle_until(t * 1_000_000)
        servos[1].set_reading(servos[1].reading, t * 1_000_000)      # read afresh
        noisy.append(servos[1].value("present_position"))
    assert len(set(noisy)) > 3 and all(abs(v - 768) < 40 for v in noisy)
    bus.idle_until(12_500_000)
    servos[0].advance_to(12_500_000)
    assert servos[0].value("present_position") == 768                # true again
    # seeded: the same seed reads the same noise
    again = Faults(scenario_mod.parse({"faults": section}).faults, seed=7)
    assert again.entries == faults.entries


def test_id_conflict_collides_and_our_firmware_rides_through_counting_it():
    r, _ = run_with(id_conflict=[{"id": 5, "as_id": 6, "at_s": 1.0, "until_s": 1.5}])
    assert r.faults["id_conflict"] == 1 and r.faults["id_conflict_end"] == 1
    assert r.faults["collision"] > 0                   # two servos answer id 6 at once
    assert r.faults["detected_corrupt_replies"] > 0    # what the firmware saw
    assert r.stop_reason is None and r.firmware.state == "walking"


def test_switch_stuck_and_bounce_reach_the_firmware_as_edges():
    r, _ = run_with(switch_stuck=[{"leg": 0, "pressed": True, "at_s": 1.0}])
    assert r.faults["switch_stuck"] == 1 and r.switch_edges == 1
    assert r.stop_reason is None and r.firmware.state == "walking"
    longer = [e for e in r.tactile_events if e.get("overcoming") and e["leg"] == "LF"]
    assert longer and longer[0]["step_length_m"] == pytest.approx(0.10)   # l_k = 2 l_i
    # a 30 ms chatter seen by a 50 Hz reader; 20 ms would alias to no edge at all
    r, _ = run_with(switch_bounce=[{"leg": 2, "period_s": 0.03, "at_s": 1.0, "until_s": 1.6}])
    assert r.faults["switch_bounce"] == 1 and r.switch_edges >= 10
    assert r.stop_reason is None and r.firmware.state == "walking"


@pytest.mark.parametrize("faults,message", [
    ({"brownout": [{"id": 5}]}, "key 'brownout.at_s' is required"),
    ({"switch_stuck": [{"leg": 7, "pressed": True, "at_s": 1.0}]}, "leg' must be 0-5"),
    ({"switch_stuck": [{"leg": 1, "pressed": 1, "at_s": 1.0}]}, "must be true or false"),
    ({"position_noise": [{"id": 1, "sigma": -1.0, "at_s": 0.0}]}, "sigma >= 0"),
    ({"id_conflict": [{"id": 1, "as_id": 300, "at_s": 0.0}]}, "0-253"),
    ({"overload": [{"id": 1, "at_s": 0.0, "volts": 3.0}]}, "unknown key 'overload.volts'"),
])
def test_bad_entries_are_one_line_errors(faults, message):
    with pytest.raises(UserError, match=message):
        Simulator(scenario(faults=faults), seed=0)


def test_run_inject_before_and_from_a_host_node():
    with Run(scenario(), duration_s=RUN_S, runtime="micropython") as run:
        entry = run.inject("overload", id=3, at_s=1.0)
        assert (entry.kind.value, entry.id, entry.at_s) == ("overload", 3, 1.0)
        with pytest.raises(UserError, match="unknown fault kind 'meltdown'"):
            run.inject("meltdown", id=3)
        r = run.run()
    assert r.faults["overload"] == 1 and r.firmware.state == "safe_stop"

    class Brownouts:
        """A host node that browns servo 4 out once, at its first tick after 1 s."""
        period_us = 100_000

        def __init__(self, run: Run) -> None:
            self.run, self.done = run, False

        def tick(self, t_us: int) -> None:
            if t_us >= 1_000_000 and not self.done:
                self.done = True
                self.run.inject("brownout", id=4)

    with Run(scenario(), duration_s=RUN_S, runtime="micropython") as run:
        run.add_node(Brownouts(run))
        r = run.run()
    assert r.faults["brownout"] == 1


def test_hexhil_bus_takes_faults_on_stdin_in_real_time():
    proc = subprocess.Popen([*HEXHIL, "bus", "--pty", "--json", "--servos", "3", "--inject-stdin"],
                            cwd=ROOT, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        path = proc.stdout.readline().strip().split(": ", 1)[1]
        port = sdk.PortHandler(path)
        assert port.openPort() and port.setBaudRate(1_000_000)
        ph = sdk.PacketHandler(1.0)
        assert ph.write1ByteTxRx(port, 2, ax12.TORQUE_ENABLE, 1) == (sdk.COMM_SUCCESS, 0)
        proc.stdin.write("brownout id=2\nmeltdown id=1\noverload id=3\n")
        proc.stdin.flush()
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            torque, result, _ = ph.read1ByteTxRx(port, 2, ax12.TORQUE_ENABLE)
            if result == sdk.COMM_SUCCESS and torque == 0:
                break
            time.sleep(0.05)
        assert (torque, result) == (0, sdk.COMM_SUCCESS)   # rebooted: torque off
        _, result, error = ph.read1ByteTxRx(port, 3, ax12.TORQUE_ENABLE)
        assert result == sdk.COMM_SUCCESS and error & 0x20   # the Overload bit
        port.closePort()
    finally:
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=20)
    assert proc.returncode == 0 and "Traceback" not in err, err
    assert "unknown fault kind 'meltdown'" in err
    summary = json.loads(out.strip().splitlines()[-1])
    assert summary["faults"]["brownout"] == 1 and summary["faults"]["overload"] == 1


def test_can_sensor_node_silent_then_garbage_on_the_real_time_rig():
    """`hexhil bus --world`'s CAN sensor node (limit_switches at 10 Hz): silent, then
    babbling frames our DBC does not define, then itself again. Our firmware reads the
    switches from the servo bus's sensor node, never these frames: no reaction of its own;
    a CAN client sees the gap (its `sequence` jumps) or frames it cannot decode."""
    from hexhil.hil.run.realtime_rig import RealTimeRig
    from hexhil.protocol import can_frames as cf

    sc = scenario(faults={"can_silent": [{"at_s": 0.5, "until_s": 1.0}],
                          "can_garbage": [{"at_s": 1.5, "until_s": 2.0}]})
    rig = RealTimeRig(sc, 0, sensor_id=None)
    port = rig.can.endpoint("rx")
    seen = []
    for t_us in range(0, 2_500_000, 50_000):
        rig.bus.idle_until(t_us)
        rig.tick(t_us)
        seen += [(m.timestamp, m.arbitration_id) for m in port.frames()]
    rig.close()
    switches = [t for t, i in seen if i == cf.ID_LIMIT_SWITCHES]
    garbage = [(t, i) for t, i in seen if i != cf.ID_LIMIT_SWITCHES]
    assert switches and not [t for t in switches if 0.5 <= t < 1.0 or 1.5 <= t < 2.0]
    assert garbage and all(1.5 <= t < 2.0 and i >= 0x700 for t, i in garbage)
    assert [t for t in switches if t >= 2.0]                   # itself again
    assert rig.core.faults.counts["can_silent"] == 1 and rig.core.faults.counts["can_garbage"] == 1


def _beams(faults: dict):
    import tomllib

    sc = tomllib.loads((ROOT / "scenarios" / "beams-stiff.toml").read_text())
    sc["_path"] = "beams-stiff"
    sc["traversal"]["max_time_s"] = 1.0
    sc["faults"] = faults
    with Run(sc) as run:
        return run.run()


def test_force_sensor_dropout_and_bias_on_seed_000():
    """Seed 000's host loop has no sensor-fault detection: without force samples it never
    plans and keeps its gentle push (stuck, no harm); a biased sensor gives a wrong
    stiffness estimate and a wrong plan (pitch instead of roll on stiff beams)."""
    r = _beams({"force_dropout": [{"at_s": 0.0}]})
    assert r.faults == {"force_dropout": 1}
    assert r.host_nodes["force_samples"] == 0 and r.host_nodes["mode"] == "none"
    assert not r.host_nodes["traversed"] and not r.host_nodes["flipped"]
    r = _beams({"force_bias": [{"at_s": 0.0, "fx_n": 0.5}]})
    assert r.faults == {"force_bias": 1} and r.host_nodes["force_samples"] > 0
    assert r.host_nodes["estimate"]["k1"] < 0.1 < 0.25             # truth 0.25 N m/rad
    assert r.host_nodes["mode"] != "roll" and not r.host_nodes["traversed"]


def test_a_switch_fault_takes_the_legs_name_as_the_docs_name_it() -> None:
    from hexhil.hil import scenario

    by_name = scenario.parse({"faults": {"switch_stuck": [
        {"leg": "rf", "pressed": True, "at_s": 1.0}],
        "switch_bounce": [{"leg": "LH", "period_s": 0.03, "at_s": 1.0}]}}, "legs")
    assert by_name.faults.switch_stuck[0].leg == 3      # LF LM LH RF RM RH
    assert by_name.faults.switch_bounce[0].leg == 2
