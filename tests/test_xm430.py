"""The third servo model, added through the seam (its table, protocol/dynamixel/xm430.py, and
one entry in protocol/dynamixel/models.py): the stock dynamixel-sdk pings, reads and
sync-writes `hexhil bus --model xm430-w350`, `hexhil conformance --model xm430-w350` passes,
and its current-based position mode caps the torque by Goal Current (e-manual)."""
from __future__ import annotations

import math
import os
import time
from typing import Iterator

import dynamixel_sdk as sdk
import dynamixel_sdk.port_handler
import pytest

from hexhil.hil.run import rig
from hexhil.hil.servobus.protocols.v2 import Bus2
from hexhil.hil.servobus.xseries_servo import XSeriesServo
from hexhil.protocol.dynamixel import models
from hexhil.protocol.dynamixel import v2 as dx2
from hexhil.protocol.dynamixel import xl430
from hexhil.protocol.dynamixel import xm430 as xm
from test_conformance_checker import conformance
from test_sdk_pty import bus_server
from test_v2_sdk_pty import retry

PH = sdk.PacketHandler(2.0)
IDS = range(1, 7)


@pytest.fixture(scope="module")
def port() -> Iterator[sdk.PortHandler]:
    mp = pytest.MonkeyPatch()
    mp.setattr(dynamixel_sdk.port_handler, "LATENCY_TIMER",
               int(os.environ.get("HEXHIL_SDK_LATENCY_MS", "1")))
    with bus_server("--model", "xm430-w350", "--ids", "1-6") as path:
        p = sdk.PortHandler(path)
        assert p.openPort() and p.setBaudRate(1_000_000)
        yield p
        p.closePort()
    mp.undo()


def test_the_model_is_one_registry_entry() -> None:
    assert models.MODELS[xm.MODEL_NAME] == (xm, 2)
    assert models.by_number(2, 1020) == xm.MODEL_NAME and models.by_number(1, 1020) is None
    built = rig.build({"bus": {"model": "xm430-w350", "servos": 3}})
    assert isinstance(built.bus, Bus2)
    assert all(isinstance(s, XSeriesServo) and s.layout is xm for s in built.bus.servos)
    assert built.bus.servos[0].value("current_limit") == 1193


def test_the_sdk_pings_reads_and_sync_writes(port) -> None:
    for i in IDS:
        assert retry(lambda: PH.ping(port, i)) == (xm.MODEL_NUMBER, sdk.COMM_SUCCESS, 0)
    found, result = PH.broadcastPing(port)
    assert result == sdk.COMM_SUCCESS and sorted(found) == list(IDS)
    assert retry(lambda: PH.read2ByteTxRx(port, 2, xm.CURRENT_LIMIT)) == (1193, sdk.COMM_SUCCESS, 0)
    assert retry(lambda: PH.read1ByteTxRx(port, 2, xm.TEMPERATURE_LIMIT)) == (80, sdk.COMM_SUCCESS, 0)
    for i in IDS:   # Return Delay 0 (see test_v2_sdk_pty), then current-based position control
        assert retry(lambda: PH.write1ByteTxRx(port, i, xm.RETURN_DELAY_TIME, 0)) == \
            (sdk.COMM_SUCCESS, 0)
        assert retry(lambda: PH.write1ByteTxRx(port, i, xm.OPERATING_MODE,
                                               xm.MODE_CURRENT_POSITION)) == (sdk.COMM_SUCCESS, 0)
        assert retry(lambda: PH.write2ByteTxRx(port, i, xm.CURRENT_LIMIT, 500)) == \
            (sdk.COMM_SUCCESS, 0)
        assert retry(lambda: PH.write1ByteTxRx(port, i, xm.TORQUE_ENABLE, 1)) == \
            (sdk.COMM_SUCCESS, 0)
    # a Goal Current above Current Limit is refused (Data Limit error)
    assert retry(lambda: PH.write2ByteTxRx(port, 1, xm.GOAL_CURRENT, 501)) == \
        (sdk.COMM_SUCCESS, dx2.ERR_DATA_LIMIT)
    current = sdk.GroupSyncWrite(port, PH, xm.GOAL_CURRENT, 2)
    for i in IDS:
        assert current.addParam(i, list((400).to_bytes(2, "little")))
    assert current.txPacket() == sdk.COMM_SUCCESS
    goals = {i: 2048 + (40 * i if i % 2 else -40 * i) for i in IDS}
    gsw = sdk.GroupSyncWrite(port, PH, xm.GOAL_POSITION, 4)
    for i in IDS:
        assert gsw.addParam(i, list(goals[i].to_bytes(4, "little")))
    assert gsw.txPacket() == sdk.COMM_SUCCESS
    time.sleep(0.3)                        # at most 240 pulses at 46 rpm: under 0.1 s
    gsr = sdk.GroupSyncRead(port, PH, xm.GOAL_CURRENT, 2)
    for i in IDS:
        assert gsr.addParam(i)
    assert retry(gsr.txRxPacket) == sdk.COMM_SUCCESS
    assert {i: gsr.getData(i, xm.GOAL_CURRENT, 2) for i in IDS} == {i: 400 for i in IDS}
    gsr = sdk.GroupSyncRead(port, PH, xm.PRESENT_POSITION, 4)
    for i in IDS:
        assert gsr.addParam(i)
    assert retry(gsr.txRxPacket) == sdk.COMM_SUCCESS
    assert {i: gsr.getData(i, xm.PRESENT_POSITION, 4) for i in IDS} == goals


def test_conformance_passes_on_it() -> None:
    with bus_server("--model", "xm430-w350", "--ids", "1-4") as path:
        rc, result, out = conformance(path, "--model", "xm430-w350", "--ids", "1-4")
    assert rc == 0 and result["ok"] and result["failed"] == 0 and result["skipped"] == 0, out
    assert result["servos"] == [1, 2, 3, 4] and result["protocol"] == 2
    assert {"restored", "sync_read_order", "fast_bulk_read"} <= {c["check"] for c in result["checks"]}


class Recorded:
    """An actuator that keeps what the servo commands (the drive seam, hil/servobus/drive.py)."""

    def __init__(self) -> None:
        self.calls: list[tuple] = []

    def command(self, goal_rad, speed_limit_rad_s, torque_limit_frac, enabled, compliance):
        self.calls.append((goal_rad, speed_limit_rad_s, torque_limit_frac, enabled))

    def state(self) -> tuple[float, float, float]:
        return 0.0, 0.0, -0.5

    def advance_to(self, t_us: int) -> None:
        pass


def test_goal_current_caps_the_torque_in_the_current_modes() -> None:
    act = Recorded()
    s = XSeriesServo(1, actuator=act, layout=xm)
    assert s.handle(dx2.WRITE, bytes((xm.OPERATING_MODE, 0, xm.MODE_CURRENT_POSITION)),
                    False, 0) is not None
    t = xm.EEPROM_BUSY_US          # deaf until then after the EEPROM write
    s.handle(dx2.WRITE, bytes((xm.GOAL_CURRENT, 0)) + (300).to_bytes(2, "little"), False, t)
    s.handle(dx2.WRITE, bytes((xm.TORQUE_ENABLE, 0, 1)), False, t + 10)
    s.handle(dx2.WRITE, bytes((xm.GOAL_POSITION, 0)) + (2148).to_bytes(4, "little"), False,
             t + 20)
    goal, _, torque, enabled = act.calls[-1]
    assert enabled and goal == pytest.approx(xm.position_to_rad(2148))
    assert torque == pytest.approx(300 * xm.CURRENT_A_PER_UNIT / xm.STALL_CURRENT_A)
    # current control: the torque's sign is the goal's direction
    s.handle(dx2.WRITE, bytes((xm.TORQUE_ENABLE, 0, 0)), False, t + 30)
    s.handle(dx2.WRITE, bytes((xm.OPERATING_MODE, 0, xm.MODE_CURRENT)), False, 50_000)
    s.handle(dx2.WRITE, bytes((xm.GOAL_CURRENT, 0)) + (-200).to_bytes(2, "little", signed=True),
             False, 60_000)
    s.handle(dx2.WRITE, bytes((xm.TORQUE_ENABLE, 0, 1)), False, 70_000)
    goal, _, torque, _ = act.calls[-1]
    assert goal == -math.inf and torque == pytest.approx(200 * 0.00269 / 2.3)
    # a load reads back as Present Current, in 2.69 mA units of the stall current
    assert s.value("present_current") == round(-0.5 * 2.3 / 0.00269)


def test_an_xl430_has_no_current_modes() -> None:
    s = XSeriesServo(1)
    assert s.layout is xl430 and s.model == "xl430-w250"
    reply = s.handle(dx2.WRITE, bytes((xl430.OPERATING_MODE, 0, 5)), False, 0)
    assert dx2.Parser().feed(reply)[0].error == dx2.ERR_DATA_RANGE
