"""A robot's own logs, written by the libraries' own writers (python-can's ASC, BLF and
candump -L writers, rosbags' rosbag2 writer, sigrok-cli's .sr), imported as traces,
replayed into the firmware, and the servo line's master checked; bad logs are one line,
exit 2."""
from __future__ import annotations

import json
import shutil
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import can
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import uart_wave
from hil import scenario
from hil.run.lockstep import Simulator
from host_tools.cli import main
from host_tools.trace import recorder as rec
from host_tools.trace.protobuf import CanFrame, SerialBytes
from host_tools.trace.reader import Trace
from protocol.dynamixel import ax12

ROOT = Path(__file__).resolve().parent.parent
HEXHIL = [sys.executable, "-m", "host_tools.cli"]
RATE_HZ = 8_000_000
BAUD = 1_000_000


def _cli(capsys, *argv: str) -> tuple[int, str, str]:
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


def _serial(path: Path) -> list[tuple[int, str, bytes]]:
    with Trace(path) as tr:
        out = []
        for m in tr.messages(["/serial"]):
            s = SerialBytes.FromString(m.data)
            if s.data:
                out.append((m.log_time_ns // 1000, s.direction, bytes(s.data)))
    return out


def _frames(path: Path) -> list[tuple[int, str, int, bytes]]:
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
    wave = uart_wave.samples(_serial(run), BAUD, RATE_HZ, direction=True)
    return uart_wave.write_sr(run.with_name("run.sr"), wave, RATE_HZ)


def _streams(bursts) -> dict[str, bytes]:
    return {d: b"".join(data for _, who, data in bursts if who == d) for d in ("tx", "rx")}


def test_a_sigrok_capture_imports_as_the_lines_bytes_at_their_times(run, run_sr, capsys):
    with zipfile.ZipFile(run_sr) as z:   # sigrok-cli's own writer made it
        assert "metadata" in z.namelist() and any(n.startswith("logic-1") for n in z.namelist())
    out = run_sr.with_name("imported.mcap")
    rc, said, err = _cli(capsys, "trace", "import", run_sr, "--out", out, "--json")
    assert rc == 0, err
    r = json.loads(said.strip().splitlines()[-1])
    assert (r["baud"], r["protocol"], r["direction_channel"], r["framing_errors"]) == \
        (BAUD, 1, "2", 0)
    original, imported = _serial(run), _serial(out)
    assert _streams(imported) == _streams(original)
    starts = {t for t, _, _ in original}
    assert all(t in starts for t, _, _ in imported)   # every byte time kept to the us


def test_without_a_direction_channel_the_packets_say_who_sent(run, tmp_path, capsys):
    wave = uart_wave.samples(_serial(run), BAUD, RATE_HZ, direction=False)
    sr = uart_wave.write_sr(tmp_path / "one_wire.sr", wave, RATE_HZ, channels=1)
    out = tmp_path / "one_wire.mcap"
    rc, said, err = _cli(capsys, "trace", "import", sr, "--out", out)
    assert rc == 0, err
    assert _streams(_serial(out)) == _streams(_serial(run))


@pytest.mark.parametrize("suffix", [".asc", ".blf", ".log"])
def test_capture_and_can_log_replay_into_the_firmware_identically(run, run_sr, tmp_path,
                                                                  capsys, suffix):
    """The run's CAN through python-can's own writer (trace export uses ASCWriter,
    BLFWriter, CanutilsLogWriter), its line through sigrok-cli: replayed, identical."""
    log = tmp_path / f"can{suffix}"
    assert _cli(capsys, "trace", "export", run, log)[0] == 0
    out = tmp_path / "robot.mcap"
    rc, said, err = _cli(capsys, "trace", "import", run_sr, log, "--out", out)
    assert rc == 0, err
    assert [f[1:] for f in _frames(out)] == [f[1:] for f in _frames(run)]
    assert [f[0] for f in _frames(out)] == [f[0] - _frames(run)[0][0] for f in _frames(run)]
    rc, said, err = _cli(capsys, "replay", out)
    assert rc == 0, said + err
    assert said.startswith("identical: ") and "11 controller CAN frames" in said


def test_python_can_writers_logs_import_with_direction_and_dbc_names(tmp_path, capsys):
    from protocol import can_frames

    msgs = []
    for i in range(5):
        arb, data = can_frames.encode("force", fx_n=0.25 * i, fy_n=0.0, fz_n=0.5, sample=i)
        msgs.append(can.Message(timestamp=1e9 + 0.01 * i, arbitration_id=arb, data=data,
                                is_rx=True, is_extended_id=False, channel=0))
    msgs.append(can.Message(timestamp=1e9 + 0.05, arbitration_id=0x700, data=bytes(8),
                            is_rx=False, is_extended_id=False, channel=0))
    for suffix, writer in ((".asc", can.ASCWriter), (".blf", can.BLFWriter),
                           (".log", can.CanutilsLogWriter)):
        path = tmp_path / f"robot{suffix}"
        w = writer(str(path))
        for m in msgs:
            w.on_message_received(m)
        w.stop()
        out = tmp_path / f"robot{suffix}.mcap"
        rc, _, err = _cli(capsys, "trace", "import", path, "--out", out)
        assert rc == 0, err
        got = _frames(out)
        assert [(t, d) for t, d, _, _ in got] == [(0, "rx"), (10_000, "rx"), (20_000, "rx"),
                                                  (30_000, "rx"), (40_000, "rx"), (50_000, "tx")]
        with Trace(out) as tr:
            forces = [v for _, v in tr.decoded(["/can/force"])]
        assert [f["fx_n"] for f in forces] == pytest.approx([0.0, 0.25, 0.5, 0.75, 1.0])


# -- rosbag2 -------------------------------------------------------------------------------
FRAME_MSG = "uint32 id\nbool is_rtr\nbool is_extended\nbool is_error\nuint8 dlc\nuint8[8] data\n"
BAG_MAP = """
[topics."/can_tx"]
as = "can"
direction = "tx"
[topics."/joint_states"]
as = "joints"
[topics."/foot_switches"]
as = "switches"
"""


def _bag(path: Path, run: Path, press_at_ns: int | None, storage: str = "sqlite3") -> Path:
    """A bag of the run's controller CAN frames (can_msgs/msg/Frame, defined in the bag),
    joint states and a switch word, by rosbags' own writer."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore, get_types_from_msg

    store = get_typestore(Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg(FRAME_MSG, "can_msgs/msg/Frame"))
    T = store.types
    t0 = 1_700_000_000 * 10**9
    with Writer(path, version=9, storage_plugin=StoragePlugin[storage.upper()]) as w:
        c = w.add_connection("/can_tx", "can_msgs/msg/Frame", typestore=store)
        j = w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=store)
        s = w.add_connection("/foot_switches", "std_msgs/msg/UInt8", typestore=store)
        items = []
        for t_us, _, arb, data in _frames(run):
            items.append((t_us * 1000, c, T["can_msgs/msg/Frame"](
                id=arb, is_rtr=False, is_extended=False, is_error=False, dlc=len(data),
                data=np.frombuffer(data.ljust(8, b"\0"), dtype=np.uint8).copy())))
        for k in range(3):
            items.append((k * 100_000_000, j, T["sensor_msgs/msg/JointState"](
                header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](
                    sec=0, nanosec=0), frame_id=""), name=["coxa", "femur"],
                position=np.array([0.1 * k, -0.1 * k]), velocity=np.array([0.0, 0.5]),
                effort=np.array([], dtype=np.float64))))
        items.append((0, s, T["std_msgs/msg/UInt8"](data=0)))
        if press_at_ns is not None:
            items.append((press_at_ns, s, T["std_msgs/msg/UInt8"](data=0b000001)))
        for t, conn, msg in sorted(items, key=lambda i: i[0]):
            w.write(conn, t0 + t, store.serialize_cdr(msg, conn.msgtype))
    return path


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_a_rosbag2_maps_to_joints_switches_and_can(run, tmp_path, capsys, storage):
    bag = _bag(tmp_path / "bag", run, press_at_ns=150_000_000, storage=storage)
    (tmp_path / "map.toml").write_text(BAG_MAP)
    out = tmp_path / "bag.mcap"
    rc, _, err = _cli(capsys, "trace", "import", bag, "--map", tmp_path / "map.toml",
                      "--out", out)
    assert rc == 0, err
    with Trace(out) as tr:
        joints = [v for _, v in tr.decoded(["/joints"])]
        edges = [(m.log_time_ns // 1000, v) for m, v in tr.decoded(["/switches"])]
    assert [j["position"] for m in joints for j in m["joints"]] == \
        pytest.approx([0, 0, 0.1, -0.1, 0.2, -0.2])
    assert [j["name"] for j in joints[0]["joints"]] == ["coxa", "femur"]
    assert [j["velocity"] for j in joints[0]["joints"]] == [0.0, 0.5]
    assert [(t, e["leg"], e["level"]) for t, e in edges] == [(150_000, 0, True)]
    assert [f[1:] for f in _frames(out)] == [("tx", a, d) for _, _, a, d in _frames(run)]


def test_a_bags_switch_reaches_the_firmware_at_its_logged_time(run, run_sr, tmp_path, capsys):
    (tmp_path / "map.toml").write_text(BAG_MAP)
    quiet = _bag(tmp_path / "quiet", run, press_at_ns=None)
    out = tmp_path / "quiet.mcap"
    assert _cli(capsys, "trace", "import", run_sr, quiet, "--map", tmp_path / "map.toml",
                "--out", out)[0] == 0
    rc, said, err = _cli(capsys, "replay", out)
    assert rc == 0 and said.startswith("identical"), said + err
    pressed = _bag(tmp_path / "pressed", run, press_at_ns=100_000_000)
    out = tmp_path / "pressed.mcap"
    assert _cli(capsys, "trace", "import", run_sr, pressed, "--map", tmp_path / "map.toml",
                "--out", out)[0] == 0
    rc, said, err = _cli(capsys, "replay", out)
    assert rc == 1, said + err
    # the firmware heard leg LF pressed at 0.1 s: its next tactile frame differs from the log's
    assert said.startswith("DIVERGED at t=0.1") and " on can:" in said and "C 140#" in said


# -- the master check on a capture ----------------------------------------------------------
def test_our_firmwares_captured_line_passes_the_master_check(run_sr, capsys):
    rc, said, err = _cli(capsys, "conformance", "--capture", run_sr, "--json")
    assert rc == 0, said + err
    r = json.loads(said.strip().splitlines()[-1])
    assert r["ok"] and r["violations"]["total"] == 0 and r["servos"] == list(range(1, 19))
    assert r["line"]["return_delay_us"]["1"]["max"] == 500    # the AX-12's default 500 us


@pytest.fixture(scope="module")
def sdk_session(tmp_path_factory) -> Path:
    """The stock dynamixel-sdk on `hexhil bus --pty`, recorded by the bus: pings, an EEPROM
    write (Return Delay Time) with the wait it needs, then a goal written and read back."""
    import dynamixel_sdk as sdk

    path = tmp_path_factory.mktemp("sdk") / "bus.mcap"
    proc = subprocess.Popen([*HEXHIL, "bus", "--pty", "--servos", "3", "--out", str(path)],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline().strip()
        assert line.startswith("pty: "), (line, proc.stderr.read() if proc.poll() else "")
        port = sdk.PortHandler(line.split(": ", 1)[1])
        assert port.openPort() and port.setBaudRate(BAUD)
        ph = sdk.PacketHandler(1.0)
        for i in (1, 2, 3):
            assert ph.ping(port, i)[1] == sdk.COMM_SUCCESS
        assert ph.write1ByteTxRx(port, 1, ax12.RETURN_DELAY_TIME, 100)[0] == sdk.COMM_SUCCESS
        time.sleep(0.03)                      # the EEPROM write's wait, and more
        assert ph.write2ByteTxRx(port, 1, ax12.GOAL_POSITION, 600)[0] == sdk.COMM_SUCCESS
        assert ph.read2ByteTxRx(port, 1, ax12.GOAL_POSITION)[:2] == (600, sdk.COMM_SUCCESS)
        port.closePort()
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.communicate(timeout=20)
    assert proc.returncode == 0
    return path


def _sdk_capture(bursts, path: Path) -> Path:
    wave = uart_wave.samples(bursts, BAUD, RATE_HZ)
    return uart_wave.write_sr(path, wave, RATE_HZ, channels=1)


def test_the_stock_sdks_captured_master_passes(sdk_session, capsys):
    sr = _sdk_capture(_serial(sdk_session), sdk_session.with_name("sdk.sr"))
    rc, said, err = _cli(capsys, "conformance", "--capture", sr)
    assert rc == 0, said + err
    assert "master violations: none" in said and "servos 1,2,3" in said
    assert "id 1 200-500 us" in said   # its return delay, before and after the EEPROM write


def test_a_write_moved_into_the_eeprom_wait_fails_named(sdk_session, capsys):
    bursts = _serial(sdk_session)
    goal = next(k for k, (_, d, data) in enumerate(bursts)
                if d == "tx" and data[4] == 3 and data[5] == ax12.GOAL_POSITION)
    eeprom = next(k for k, (_, d, data) in enumerate(bursts)
                  if d == "tx" and data[4] == 3 and data[5] == ax12.RETURN_DELAY_TIME)
    # the goal write and its status, moved to 1 ms after the EEPROM write's status
    t_status = bursts[eeprom + 1][0]
    shift = t_status + 1_000 - bursts[goal][0]
    moved = [(t + shift, d, data) for t, d, data in bursts[goal:goal + 2]]
    rest = bursts[:goal] + bursts[goal + 2:]
    sr = _sdk_capture(sorted(rest + moved), sdk_session.with_name("moved.sr"))
    rc, said, err = _cli(capsys, "conformance", "--capture", sr)
    assert rc == 1, said + err
    assert "eeprom_busy: WRITE id 1 Goal Position (30) = 600 (WRITE while id 1 writes its " \
           "EEPROM)" in said
    assert "master violations: eeprom_busy 1" in said


# -- every import checked ----------------------------------------------------------------
def _refused(capsys, *argv) -> str:
    rc, out, err = _cli(capsys, *argv)
    assert rc == 2 and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    return err


def test_a_truncated_capture_is_one_line(run_sr, tmp_path, capsys):
    cut = tmp_path / "cut.sr"
    cut.write_bytes(run_sr.read_bytes()[: run_sr.stat().st_size // 2])
    err = _refused(capsys, "trace", "import", cut, "--out", tmp_path / "x.mcap")
    assert "truncated" in err
    assert not (tmp_path / "x.mcap").exists() and not (tmp_path / "x.mcap.partial").exists()
    assert "truncated" in _refused(capsys, "conformance", "--capture", cut)


def test_a_capture_at_the_wrong_sample_rate_or_baud_is_one_line(run, tmp_path, capsys):
    bursts = _serial(run)[:40]
    wave = uart_wave.samples(bursts, BAUD, RATE_HZ)
    mislabelled = uart_wave.write_sr(tmp_path / "five.sr", wave, 5_000_000, channels=1)
    err = _refused(capsys, "trace", "import", mislabelled, "--out", tmp_path / "x.mcap")
    assert "baud not found" in err and "625" in err     # 1 Mbit/s read at 5/8 of its rate
    slow = uart_wave.write_sr(tmp_path / "slow.sr", uart_wave.samples(bursts, BAUD, 2_000_000),
                              2_000_000, channels=1)
    assert "too low" in _refused(capsys, "trace", "import", slow, "--out", tmp_path / "x.mcap")
    odd = uart_wave.write_sr(tmp_path / "odd.sr", uart_wave.samples(bursts, 700_000, RATE_HZ),
                             RATE_HZ, channels=1)
    assert "baud not found" in _refused(capsys, "trace", "import", odd, "--out",
                                        tmp_path / "x.mcap")


def test_truncated_can_logs_are_one_line(tmp_path, capsys):
    msgs = [can.Message(timestamp=1e9 + 0.01 * i, arbitration_id=0x120, data=bytes([i] * 8),
                        is_extended_id=False) for i in range(40)]
    for suffix, writer, cut in ((".asc", can.ASCWriter, 300), (".blf", can.BLFWriter, 100),
                                (".log", can.CanutilsLogWriter, 7)):
        path = tmp_path / f"full{suffix}"
        w = writer(str(path))
        for m in msgs:
            w.on_message_received(m)
        w.stop()
        short = tmp_path / f"short{suffix}"
        short.write_bytes(path.read_bytes()[:-cut])
        err = _refused(capsys, "trace", "import", short, "--out", tmp_path / "x.mcap")
        assert "truncated" in err, (suffix, err)
        assert not (tmp_path / "x.mcap").exists()


def test_an_unknown_topic_or_bad_map_is_one_line(run, tmp_path, capsys):
    bag = _bag(tmp_path / "bag", run, press_at_ns=None)
    (tmp_path / "map.toml").write_text(BAG_MAP + '[topics."/imu"]\nas = "joints"\n')
    err = _refused(capsys, "trace", "import", bag, "--map", tmp_path / "map.toml",
                   "--out", tmp_path / "x.mcap")
    assert "unknown topic /imu" in err and "/joint_states" in err
    (tmp_path / "map.toml").write_text('[topics."/joint_states"]\nas = "imu"\n')
    assert "unknown as" in _refused(capsys, "trace", "import", bag, "--map",
                                    tmp_path / "map.toml", "--out", tmp_path / "x.mcap")
    (tmp_path / "map.toml").write_text("[serail]\nbaud = 1\n")
    assert "unknown map section" in _refused(capsys, "trace", "import", bag, "--map",
                                             tmp_path / "map.toml", "--out",
                                             tmp_path / "x.mcap")
    assert "--map" in _refused(capsys, "trace", "import", bag, "--out", tmp_path / "x.mcap")
    assert not (tmp_path / "x.mcap").exists()
    shutil.rmtree(bag)


def test_a_protocol_2_line_imports_replays_and_passes(tmp_path, capsys):
    """X-series servos (Protocol 2.0, CRC and stuffing) on one wire: the capture is told
    apart by its headers, its status packets by their instruction 0x55."""
    path = tmp_path / "x.mcap"
    s = {section: {} for section in scenario.SCHEMA}
    s["bus"] = {"model": "xl430-w250"}
    with rec.Recorder(path, {"scenario": "x"}, protocol=2) as r:
        assert Simulator(s, seed=0, recorder=r).run(duration_s=0.3,
                                                     python="micropython").exit_code == 0
    sr = uart_wave.write_sr(tmp_path / "x.sr", uart_wave.samples(_serial(path), BAUD, RATE_HZ),
                            RATE_HZ, channels=1)
    out = tmp_path / "imported.mcap"
    rc, said, err = _cli(capsys, "trace", "import", sr, "--out", out)
    assert rc == 0 and "Protocol 2.0" in said, said + err
    assert _streams(_serial(out)) == _streams(_serial(path))
    rc, said, err = _cli(capsys, "conformance", "--capture", sr)
    assert rc == 0 and "(xl430-w250)" in said and "master violations: none" in said, said + err
    rc, said, err = _cli(capsys, "replay", out)
    assert rc == 0 and said.startswith("identical"), said + err


def test_the_api_example_imports_checks_and_replays(run, run_sr, tmp_path, capsys):
    log = tmp_path / "can.blf"
    assert _cli(capsys, "trace", "export", run, log)[0] == 0
    r = subprocess.run([sys.executable, "examples/robot_log.py", str(run_sr), str(log),
                        str(tmp_path / "robot.mcap")], cwd=ROOT, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.splitlines() == [f"serial: {run_sr}", f"can: {log}",
                                     "master violations: 0, framing errors: 0", "identical"]


def test_a_wide_capture_in_several_chunks_reads_whole(run, tmp_path, capsys):
    """Nine channels (two bytes a sample) and more samples than one chunk of sigrok's holds:
    the chunks are read in their order, the direction found on the third channel."""
    wave = uart_wave.samples(_serial(run), BAUD, RATE_HZ, direction=True).astype(np.uint16)
    wave |= 1 << 8    # a ninth channel, held high
    raw = tmp_path / "wide.bin"
    raw.write_bytes(wave.astype("<u2").tobytes())
    sr = tmp_path / "wide.sr"
    subprocess.run(["sigrok-cli", "-I", f"binary:numchannels=9:samplerate={RATE_HZ}", "-i",
                    str(raw), "-o", str(sr)], check=True, capture_output=True)
    with zipfile.ZipFile(sr) as z:
        assert len([n for n in z.namelist() if n.startswith("logic-1-")]) > 1
    out = tmp_path / "wide.mcap"
    rc, said, err = _cli(capsys, "trace", "import", sr, "--out", out, "--json")
    assert rc == 0, err
    assert json.loads(said.splitlines()[-1])["direction_channel"] == "2"
    assert _streams(_serial(out)) == _streams(_serial(run))


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(rate=st.sampled_from(["8 MHz", "250 kHz", "1 Hz", "0 Hz", "fast", "", "3.5 GHz"]),
       unit=st.sampled_from(["1", "2", "3", "0", "x"]), probes=st.integers(-1, 20),
       samples=st.binary(max_size=4096), names=st.booleans())
def test_a_hostile_sr_file_is_read_or_refused_in_one_line(tmp_path, rate, unit, probes,
                                                          samples, names):
    from host_tools.trace.import_logs import read_servo_line
    from protocol.errors import UserError

    path = tmp_path / "hostile.sr"
    meta = f"[device 1]\ncapturefile=logic-1\ntotal probes={probes}\nsamplerate={rate}\n" \
           f"unitsize={unit}\n" + ("probe1=dir\nprobe2=data\n" if names else "")
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("version", "2")
        z.writestr("metadata", meta)
        z.writestr("logic-1-1", samples)
    try:
        line = read_servo_line(path)
    except UserError as exc:
        assert "\n" not in str(exc)
    else:
        assert line.bursts and line.baud > 0


def test_a_virtual_board_firmware_replays_a_captured_line(tmp_path, capsys):
    """Another runtime: a MicroPython main file on the virtual board (its UART and direction
    pin on the link) masters the logged line as it mastered the run's."""
    board = ROOT / "examples" / "board_tripod.py"
    flat = ROOT / "scenarios" / "flat-tripod.toml"
    run = tmp_path / "board.mcap"
    rc, said, err = _cli(capsys, "run", flat, "--firmware", board, "--duration", "0.5",
                         "--out", run)
    assert rc == 0, said + err
    sr = uart_wave.write_sr(tmp_path / "board.sr",
                            uart_wave.samples(_serial(run), BAUD, RATE_HZ, direction=True),
                            RATE_HZ)
    out = tmp_path / "imported.mcap"
    assert _cli(capsys, "trace", "import", sr, "--out", out)[0] == 0
    rc, said, err = _cli(capsys, "replay", out, "--firmware", board, "--scenario", flat)
    assert rc == 0 and said.startswith("identical"), said + err
