"""Acceptance: the official dynamixel-sdk drives `hexhil bus --pty` like a real AX-12 bus."""
from __future__ import annotations

import signal
import subprocess
import time
from contextlib import contextmanager
from typing import Iterator

import pytest

import dynamixel_sdk as sdk
import dynamixel_sdk.port_handler

from ctrl_c import sigint_default
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl
from conftest import HEXHIL, ROOT, hexhil_in_process


@contextmanager
def bus_server(*flags: str) -> Iterator[str]:
    """Run `hexhil bus --pty FLAGS`, yield the pty path; SIGTERM must end it cleanly."""
    proc = subprocess.Popen([*HEXHIL, "bus", "--pty", *flags], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline().strip()
        assert line.startswith("pty: /dev/"), (line, proc.stderr.read() if proc.poll() else "")
        yield line.split(": ", 1)[1]
    finally:
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert out.startswith("served ") and "Traceback" not in err, (out, err)


@pytest.fixture(scope="module")
def sdk_port(monkeypatch_module) -> Iterator[sdk.PortHandler]:
    with bus_server() as path:
        port = sdk.PortHandler(path)
        assert port.openPort() and port.setBaudRate(1_000_000)
        yield port
        port.closePort()


@pytest.fixture(scope="module")
def monkeypatch_module():
    mp = pytest.MonkeyPatch()
    # RX timeout = 2 x LATENCY_TIMER + 2 ms: 102 ms, generous, since a shared machine may not
    # schedule the server for a while; a missing ID costs only that once
    mp.setattr(dynamixel_sdk.port_handler, "LATENCY_TIMER", 50)
    yield mp
    mp.undo()


PH = sdk.PacketHandler(1.0)


def test_ping_all_18_and_a_missing_id(sdk_port):
    for i in range(1, 19):
        assert PH.ping(sdk_port, i) == (ax12.MODEL_NUMBER, sdk.COMM_SUCCESS, 0)
    assert PH.ping(sdk_port, 19)[1] == sdk.COMM_RX_TIMEOUT


def test_sync_write_moves_all_18_at_the_set_speed(sdk_port):
    for i in range(1, 19):
        assert PH.write1ByteTxRx(sdk_port, i, ax12.TORQUE_ENABLE, 1)[:2] == (sdk.COMM_SUCCESS, 0)
    speed = 150  # 16.65 rpm
    speed_units_s = speed * ax12.SPEED_RPM_PER_UNIT * 6.0 * ax12.POSITION_MAX / ax12.POSITION_RANGE_DEG
    start = {i: PH.read2ByteTxRx(sdk_port, i, ax12.PRESENT_POSITION)[0] for i in range(1, 19)}
    goals = {i: start[i] + (120 if i % 2 else -120) for i in range(1, 19)}
    gsw = sdk.GroupSyncWrite(sdk_port, PH, ax12.GOAL_POSITION, 4)
    for i in range(1, 19):
        assert gsw.addParam(i, list(goals[i].to_bytes(2, "little") + speed.to_bytes(2, "little")))
    assert gsw.txPacket() == sdk.COMM_SUCCESS
    t_sent = time.monotonic()
    moving = [PH.read1ByteTxRx(sdk_port, i, ax12.MOVING)[0] for i in range(1, 19)]
    assert moving == [1] * 18
    samples = []  # (seconds after the sync write, servo 1 position)
    while time.monotonic() - t_sent < 2.0:
        pos, res, err = PH.read2ByteTxRx(sdk_port, 1, ax12.PRESENT_POSITION)
        assert (res, err) == (sdk.COMM_SUCCESS, 0)
        samples.append((time.monotonic() - t_sent, pos))
        if pos == goals[1]:
            break
        time.sleep(0.02)
    assert samples[-1][1] == goals[1]
    t_move = 120 / speed_units_s  # 0.42 s: arrival, as positions sampled over time show it
    assert 0.6 * t_move < samples[-1][0] < t_move + 1.0  # never early; late only if loaded
    mid = [(t, p) for t, p in samples if 0.2 * t_move < t < 0.8 * t_move]
    if len(mid) >= 2:  # slope between samples, loosely: the machine may be loaded
        (t1, p1), (t2, p2) = mid[0], mid[-1]
        if t2 - t1 > 0.1:
            assert (p2 - p1) / (t2 - t1) == pytest.approx(speed_units_s, rel=0.35)
    time.sleep(max(0.0, t_move + 0.1 - (time.monotonic() - t_sent)))
    for i in range(1, 19):
        assert PH.read2ByteTxRx(sdk_port, i, ax12.PRESENT_POSITION)[0] == goals[i]
        assert PH.read1ByteTxRx(sdk_port, i, ax12.MOVING)[0] == 0


def test_garbage_on_the_line_then_a_successful_ping(sdk_port):
    sdk_port.writePort(bytes([0x00, 0x13, 0xFF, 0x42, 0xFF, 0xFF, 0x07, 0xC8, 0x11]))
    # FF FF 07 C8 starts a 204-byte packet: a real servo waits for it until a 100 ms gap
    time.sleep(0.15)
    sdk_port.clearPort()
    assert PH.ping(sdk_port, 3) == (ax12.MODEL_NUMBER, sdk.COMM_SUCCESS, 0)
    sdk_port.writePort(bytes([0x55, 0xAA, 0x00, 0x01]))  # garbage without a header: no wait
    assert PH.ping(sdk_port, 4) == (ax12.MODEL_NUMBER, sdk.COMM_SUCCESS, 0)


def _sdk_outcome(call):
    """What a stock SDK call returned, or the exception it raised on a garbled reply."""
    try:
        return call()
    except IndexError:  # the SDK indexes a reply it took to be complete but was empty
        return "IndexError"


def test_stock_sdk_misreads_an_echoing_line(monkeypatch_module):
    # The SDK does not strip echo: its own packet comes back first and is taken for the
    # status (typically error byte 0x02 = its READ instruction, data = its parameters).
    # Which bytes it grabs depends on pty timing, so the test pins what must never happen:
    # the SDK reading the servo's true answer.
    with bus_server("--echo", "--servos", "2") as path:
        port = sdk.PortHandler(path)
        assert port.openPort()
        try:
            ping = _sdk_outcome(lambda: PH.ping(port, 1))
            read = _sdk_outcome(lambda: PH.read2ByteTxRx(port, 2, ax12.PRESENT_POSITION))
        finally:
            port.closePort()
    assert ping != (ax12.MODEL_NUMBER, sdk.COMM_SUCCESS, 0)
    assert read == "IndexError" or read[1] != sdk.COMM_SUCCESS or read[2] != 0 \
        or read[0] != 512
    # without echo the same calls read the truth (the misreading is the echo's doing)
    with bus_server("--servos", "2") as path:
        port = sdk.PortHandler(path)
        assert port.openPort()
        try:
            assert PH.ping(port, 1) == (ax12.MODEL_NUMBER, sdk.COMM_SUCCESS, 0)
            assert PH.read2ByteTxRx(port, 2, ax12.PRESENT_POSITION) == (512, sdk.COMM_SUCCESS, 0)
        finally:
            port.closePort()


def test_cli_rejects_bad_flags_in_one_line():
    r = hexhil_in_process("bus", "--pty", "--ids", "5-2")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    r = hexhil_in_process("bus", "--pty", "--tcp", "7000")
    assert r.returncode == 2 and "one transport" in r.stderr


def test_tcp_transport_serves_pyserial_socket_url_and_ctrl_c_ends_it():
    import serial

    proc = subprocess.Popen([*HEXHIL, "bus", "--tcp", "0", "--servos", "3"], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=sigint_default)
    try:
        line = proc.stdout.readline().strip()
        assert line.startswith("tcp: 127.0.0.1:"), line
        port = int(line.rsplit(":", 1)[1])
        ser = serial.serial_for_url(f"socket://127.0.0.1:{port}", timeout=2)
        ser.write(dxl.ping(3))
        assert ser.read(6) == dxl.status(3)
        ser.close()
    finally:
        proc.send_signal(signal.SIGINT)  # Ctrl-C ends it as cleanly as SIGTERM
        out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0 and "Traceback" not in err
    assert out.splitlines()[-1].startswith("served 1 packets, 1 replies")


def test_real_time_unplug_fault_fires_on_the_wall_clock(monkeypatch_module):
    with bus_server("--servos", "2", "--unplug", "2:0:1.0") as path:
        t0 = time.monotonic()
        port = sdk.PortHandler(path)
        assert port.openPort()
        try:
            assert PH.ping(port, 1)[1] == sdk.COMM_SUCCESS
            assert PH.ping(port, 2)[1] == sdk.COMM_RX_TIMEOUT  # unplugged for the first second
            time.sleep(max(0.0, 1.2 - (time.monotonic() - t0)))
            assert PH.ping(port, 2) == (ax12.MODEL_NUMBER, sdk.COMM_SUCCESS, 0)
        finally:
            port.closePort()
