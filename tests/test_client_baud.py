"""Acceptance: the client's line settings count on `hexhil bus --pty`. A client at
another rate than a servo's Baud Rate register reaches nothing; one that follows a servo
to its new rate reaches that servo and no other, for both protocols."""
from __future__ import annotations

import os
from typing import Iterator

import dynamixel_sdk as sdk
import dynamixel_sdk.port_handler
import pytest
import serial

from hexhil.protocol.dynamixel import ax12, xl430
from hexhil.protocol.dynamixel import v1 as dxl
from hexhil.protocol.dynamixel import v2 as dx2
from test_sdk_pty import bus_server

PH1, PH2 = sdk.PacketHandler(1.0), sdk.PacketHandler(2.0)


@pytest.fixture(autouse=True)
def latency():
    mp = pytest.MonkeyPatch()
    mp.setattr(dynamixel_sdk.port_handler, "LATENCY_TIMER",
               int(os.environ.get("HEXHIL_SDK_LATENCY_MS", "10")))
    yield
    mp.undo()


@pytest.fixture()
def ax_port() -> Iterator[sdk.PortHandler]:
    with bus_server("--servos", "6") as path:
        p = sdk.PortHandler(path)
        assert p.openPort()
        yield p
        p.closePort()


def ping(ph, port, dev_id: int, tries: int = 3) -> int:
    """COMM result of a ping; a time-out is tried again (a loaded machine may be late),
    a success never is."""
    for _ in range(tries):
        _, result, _ = ph.ping(port, dev_id)
        if result == sdk.COMM_SUCCESS:
            return result
    return result


def test_ax12_client_at_57600_reaches_only_the_servo_set_to_it(ax_port):
    assert ax_port.setBaudRate(57600)
    assert all(ping(PH1, ax_port, i) != sdk.COMM_SUCCESS for i in (1, 5))
    assert ax_port.setBaudRate(1_000_000)
    assert ping(PH1, ax_port, 5) == sdk.COMM_SUCCESS
    # Baud Rate 34: 2 Mbps / 35 = 57142 bps, 0.8 % off 57600 (within a UART's tolerance)
    assert PH1.write1ByteTxRx(ax_port, 5, ax12.BAUD_RATE, 34) == (sdk.COMM_SUCCESS, 0)
    assert ping(PH1, ax_port, 5) != sdk.COMM_SUCCESS          # servo 5 left 1 Mbps
    assert ping(PH1, ax_port, 4) == sdk.COMM_SUCCESS          # the others did not
    assert ax_port.setBaudRate(57600)
    assert ping(PH1, ax_port, 5) == sdk.COMM_SUCCESS
    assert PH1.read2ByteTxRx(ax_port, 5, ax12.PRESENT_POSITION)[1:] == (sdk.COMM_SUCCESS, 0)
    assert all(ping(PH1, ax_port, i) != sdk.COMM_SUCCESS for i in (1, 2, 3, 4, 6))


def test_ax12_mismatch_is_garbage_or_silence_never_a_reply(ax_port):
    # a raw pyserial client at 115200 against 1 Mbps servos: what comes back (if anything)
    # never parses as a status packet
    ser = serial.Serial(ax_port.port_name, 115200, timeout=0.1)
    try:
        for dev_id in range(1, 7):
            ser.write(dxl.packet(dev_id, dxl.PING))
            heard = ser.read(64)
            assert dxl.Parser().feed(heard) == [], heard
    finally:
        ser.close()


def test_xl430_client_follows_a_servo_to_57600_and_to_4_5_mbps():
    with bus_server("--model", "xl430-w250", "--servos", "6") as path:
        port = sdk.PortHandler(path)
        assert port.openPort() and port.setBaudRate(57600)
        try:
            assert ping(PH2, port, 5) != sdk.COMM_SUCCESS
            assert port.setBaudRate(1_000_000)
            assert PH2.write1ByteTxRx(port, 5, xl430.BAUD_RATE, 1) == (sdk.COMM_SUCCESS, 0)
            assert PH2.write1ByteTxRx(port, 6, xl430.BAUD_RATE, 7) == (sdk.COMM_SUCCESS, 0)
            assert port.setBaudRate(57600)
            assert ping(PH2, port, 5) == sdk.COMM_SUCCESS
            assert all(ping(PH2, port, i) != sdk.COMM_SUCCESS for i in (4, 6))
        finally:
            port.closePort()
        # 4.5 Mbps is no rate the SDK accepts: pyserial sets it (BOTHER) on the same pty
        ser = serial.Serial(path, 4_500_000, timeout=0.2)
        try:
            for dev_id, answers in ((6, True), (5, False), (1, False)):
                ser.reset_input_buffer()
                ser.write(dx2.packet(dev_id, dx2.PING))
                heard = ser.read(14)
                got = [p for p in dx2.Parser().feed(heard)]
                assert bool(got) == answers, (dev_id, heard)
        finally:
            ser.close()
