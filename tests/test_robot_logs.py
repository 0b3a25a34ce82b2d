"""A robot's own logs, written by the libraries' own writers (python-can's ASC, BLF and
candump -L writers, rosbags' rosbag2 writer, sigrok-cli's .sr), imported as traces and
replayed into the firmware; bad logs are one line, exit 2. (The servo line's capture and
its master check: tests/test_capture_conformance.py.)"""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import can
import numpy as np
import pytest

import uart_wave
from hexhil.trace.reader import Trace
from robot_logs import (BAUD, RATE_HZ, ROOT, can_frames, cli, refused, run, run_sr,  # noqa: F401
                        serial_bursts)


@pytest.mark.parametrize("suffix,python", [(".asc", "micropython"), (".blf", "cpython"),
                                           (".log", "micropython")])
def test_capture_and_can_log_replay_into_the_firmware_identically(run, run_sr, tmp_path,
                                                                  capsys, suffix, python):
    """The run's CAN through python-can's own writer (trace export uses ASCWriter,
    BLFWriter, CanutilsLogWriter), its line through sigrok-cli: replayed, identical, under
    either runtime (the run was micropython's)."""
    log = tmp_path / f"can{suffix}"
    assert cli(capsys, "trace", "export", run, log)[0] == 0
    out = tmp_path / "robot.mcap"
    rc, said, err = cli(capsys, "trace", "import", run_sr, log, "--out", out)
    assert rc == 0, err
    assert [f[1:] for f in can_frames(out)] == [f[1:] for f in can_frames(run)]
    assert [f[0] for f in can_frames(out)] == [f[0] - can_frames(run)[0][0]
                                               for f in can_frames(run)]
    rc, said, err = cli(capsys, "replay", out, "--python", python)
    assert rc == 0, said + err
    assert said.startswith("identical: ") and "11 controller CAN frames" in said


def test_python_can_writers_logs_import_with_direction_and_dbc_names(tmp_path, capsys):
    from hexhil.protocol import can_frames as dbc

    msgs = []
    for i in range(5):
        arb, data = dbc.encode("force", fx_n=0.25 * i, fy_n=0.0, fz_n=0.5, sample=i)
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
        rc, _, err = cli(capsys, "trace", "import", path, "--out", out)
        assert rc == 0, err
        got = can_frames(out)
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
        for t_us, _, arb, data in can_frames(run):
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
    rc, _, err = cli(capsys, "trace", "import", bag, "--map", tmp_path / "map.toml",
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
    assert [f[1:] for f in can_frames(out)] == [("tx", a, d) for _, _, a, d in can_frames(run)]


def test_a_bags_switch_reaches_the_firmware_at_its_logged_time(run, run_sr, tmp_path, capsys):
    (tmp_path / "map.toml").write_text(BAG_MAP)
    quiet = _bag(tmp_path / "quiet", run, press_at_ns=None)
    out = tmp_path / "quiet.mcap"
    assert cli(capsys, "trace", "import", run_sr, quiet, "--map", tmp_path / "map.toml",
                "--out", out)[0] == 0
    rc, said, err = cli(capsys, "replay", out)
    assert rc == 0 and said.startswith("identical"), said + err
    pressed = _bag(tmp_path / "pressed", run, press_at_ns=100_000_000)
    out = tmp_path / "pressed.mcap"
    assert cli(capsys, "trace", "import", run_sr, pressed, "--map", tmp_path / "map.toml",
                "--out", out)[0] == 0
    rc, said, err = cli(capsys, "replay", out)
    assert rc == 1, said + err
    # the firmware heard leg LF pressed at 0.1 s: its next tactile frame differs from the log's
    assert said.startswith("DIVERGED at t=0.1") and " on can:" in said and "C 140#" in said


# -- every import checked ----------------------------------------------------------------
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
        err = refused(capsys, "trace", "import", short, "--out", tmp_path / "x.mcap")
        assert "truncated" in err, (suffix, err)
        assert not (tmp_path / "x.mcap").exists()


def test_an_unknown_topic_or_bad_map_is_one_line(run, tmp_path, capsys):
    bag = _bag(tmp_path / "bag", run, press_at_ns=None)
    (tmp_path / "map.toml").write_text(BAG_MAP + '[topics."/imu"]\nas = "joints"\n')
    err = refused(capsys, "trace", "import", bag, "--map", tmp_path / "map.toml",
                   "--out", tmp_path / "x.mcap")
    assert "unknown topic /imu" in err and "/joint_states" in err
    (tmp_path / "map.toml").write_text('[topics."/joint_states"]\nas = "imu"\n')
    assert "unknown as" in refused(capsys, "trace", "import", bag, "--map",
                                    tmp_path / "map.toml", "--out", tmp_path / "x.mcap")
    (tmp_path / "map.toml").write_text("[serail]\nbaud = 1\n")
    assert "unknown map section" in refused(capsys, "trace", "import", bag, "--map",
                                             tmp_path / "map.toml", "--out",
                                             tmp_path / "x.mcap")
    assert "--map" in refused(capsys, "trace", "import", bag, "--out", tmp_path / "x.mcap")
    assert not (tmp_path / "x.mcap").exists()
    shutil.rmtree(bag)


def test_the_api_example_imports_checks_and_replays(run, run_sr, tmp_path, capsys):
    log = tmp_path / "can.blf"
    assert cli(capsys, "trace", "export", run, log)[0] == 0
    r = subprocess.run([sys.executable, "examples/robot_log.py", str(run_sr), str(log),
                        str(tmp_path / "robot.mcap")], cwd=ROOT, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.splitlines() == [f"serial: {run_sr}", f"can: {log}",
                                     "master violations: 0, framing errors: 0", "identical"]


def test_a_virtual_board_firmware_replays_a_captured_line(tmp_path, capsys):
    """Another runtime: a MicroPython main file on the virtual board (its UART and direction
    pin on the link) masters the logged line as it mastered the run's."""
    board = ROOT / "examples" / "board_tripod.py"
    flat = ROOT / "scenarios" / "flat-tripod.toml"
    run = tmp_path / "board.mcap"
    rc, said, err = cli(capsys, "run", flat, "--firmware", board, "--duration", "0.5",
                         "--out", run)
    assert rc == 0, said + err
    sr = uart_wave.write_sr(tmp_path / "board.sr",
                            uart_wave.samples(serial_bursts(run), BAUD, RATE_HZ, direction=True),
                            RATE_HZ)
    out = tmp_path / "imported.mcap"
    assert cli(capsys, "trace", "import", sr, "--out", out)[0] == 0
    rc, said, err = cli(capsys, "replay", out, "--firmware", board, "--scenario", flat)
    assert rc == 0 and said.startswith("identical"), said + err



def test_a_log_whose_clock_jumps_past_a_traces_range_is_one_line(tmp_path, capsys):
    """Found by fuzz_logs: a candump line whose time jumped 1e11 s on made a log time
    past MCAP's 64-bit nanoseconds, and the writer's struct.error escaped."""
    log = tmp_path / "jump.log"
    log.write_text("(1000000000.000000) vcan0 100#01 R\n(100000000000.000000) vcan0 100#02 R\n")
    err = refused(capsys, "trace", "import", log, "--out", tmp_path / "x.mcap")
    assert "a log spans 0 to 1e+09 s" in err and "a time jumped" in err
    assert not (tmp_path / "x.mcap").exists() and not (tmp_path / "x.mcap.partial").exists()


def test_python_can_csv_trc_and_sqlite_logs_import_too(tmp_path, capsys):
    msgs = [can.Message(timestamp=1e9 + 0.02 * i, arbitration_id=0x120, data=bytes([i] * 8),
                        is_extended_id=False) for i in range(5)]
    for suffix in (".csv", ".trc", ".db"):
        path = tmp_path / f"robot{suffix}"
        w = can.Logger(str(path))   # python-can's CSVWriter, TRCWriter, SqliteWriter
        for m in msgs:
            w.on_message_received(m)
        w.stop()
        out = tmp_path / f"robot{suffix}.mcap"
        rc, _, err = cli(capsys, "trace", "import", path, "--out", out)
        assert rc == 0, (suffix, err)
        assert [(t, a, d) for t, _, a, d in can_frames(out)] == \
            [(20_000 * i, 0x120, bytes([i] * 8)) for i in range(5)], suffix


def test_another_firmware_diverges_at_its_first_other_packet_in_words(run_sr, tmp_path,
                                                                      capsys):
    """Our firmware's captured line replayed into another master (the board example): the
    first packet that differs, both sides in words; the other firmware is stopped there."""
    out = tmp_path / "ours.mcap"
    assert cli(capsys, "trace", "import", run_sr, "--out", out)[0] == 0
    rc, said, err = cli(capsys, "replay", out, "--firmware",
                        ROOT / "examples" / "board_tripod.py", "--json")
    assert rc == 1, said + err
    d = json.loads(said.strip().splitlines()[-1])["first_divergence"]
    assert d["topic"] == "uart" and d["exchange"] > 0
    assert d["packets"]["expected"][0].startswith("WRITE id 1 Return Delay Time (5) = 0")
    assert d["packets"]["actual"] == ["WRITE id 254 Torque Enable (24) = 1"]
