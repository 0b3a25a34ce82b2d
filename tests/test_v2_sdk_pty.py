"""Acceptance: the stock dynamixel-sdk Protocol 2.0 client drives
`hexhil bus --model xl430-w250 --pty` like a real bus of 18 XL430-W250-T."""
from __future__ import annotations

import os
import time
from typing import Iterator

import dynamixel_sdk as sdk
import dynamixel_sdk.port_handler
import pytest

from hexhil.protocol.dynamixel import v2 as dx2
from hexhil.protocol.dynamixel import xl430 as xl
from test_sdk_pty import bus_server

PH = sdk.PacketHandler(2.0)
IDS = range(1, 19)


@pytest.fixture(scope="module")
def port() -> Iterator[sdk.PortHandler]:
    mp = pytest.MonkeyPatch()
    mp.setattr(dynamixel_sdk.port_handler, "LATENCY_TIMER", int(os.environ.get("HEXHIL_SDK_LATENCY_MS", "1")))
    with bus_server("--model", "xl430-w250") as path:
        p = sdk.PortHandler(path)
        assert p.openPort() and p.setBaudRate(1_000_000)
        yield p
        p.closePort()
    mp.undo()


def retry(fn, tries: int = 20):
    """The SDK's receive timeout is a few ms at LATENCY_TIMER 1: on a loaded machine the
    server may not be scheduled in time, so a call may be repeated (never its result
    checked loosely)."""
    for _ in range(tries - 1):
        out = fn()
        # the COMM result: alone, first of (result, error), middle of (value, result, error)
        result = out if isinstance(out, int) else out[0] if len(out) == 2 else out[1]
        if result == sdk.COMM_SUCCESS:
            return out
        time.sleep(0.05)
    return fn()


def test_ping_all_18(port) -> None:
    for i in IDS:
        assert retry(lambda: PH.ping(port, i)) == (xl.MODEL_NUMBER, sdk.COMM_SUCCESS, 0)
    found, result = PH.broadcastPing(port)
    assert result == sdk.COMM_SUCCESS and sorted(found) == list(IDS)
    assert found[5] == [xl.MODEL_NUMBER, xl.FIRMWARE_VERSION]


def test_sync_write_then_sync_read_and_fast_sync_read(port) -> None:
    # The SDK waits (11 + 4) x 18 byte times + 2 x LATENCY_TIMER + 2 ms = 6.7 ms for all 18
    # status packets; at the default Return Delay (500 us) they take 11.7 ms, so a real bus
    # times out too: Return Delay 0, as X-series users set it (EEPROM: torque still off).
    for i in IDS:
        assert retry(lambda: PH.write1ByteTxRx(port, i, xl.RETURN_DELAY_TIME, 0)) == \
            (sdk.COMM_SUCCESS, 0)
    for i in IDS:
        assert retry(lambda: PH.write1ByteTxRx(port, i, xl.TORQUE_ENABLE, 1)) == \
            (sdk.COMM_SUCCESS, 0)
    goals = {i: 2048 + (37 * i if i % 2 else -37 * i) for i in IDS}
    gsw = sdk.GroupSyncWrite(port, PH, xl.GOAL_POSITION, 4)
    for i in IDS:
        assert gsw.addParam(i, list(goals[i].to_bytes(4, "little")))
    assert gsw.txPacket() == sdk.COMM_SUCCESS
    time.sleep(0.3)                       # at most 666 pulses at 57 rpm: under 0.2 s
    gsr = sdk.GroupSyncRead(port, PH, xl.PRESENT_POSITION, 4)
    for i in IDS:
        assert gsr.addParam(i)
    assert retry(gsr.txRxPacket) == sdk.COMM_SUCCESS
    assert {i: gsr.getData(i, xl.PRESENT_POSITION, 4) for i in IDS} == goals
    gsr.data_dict = {i: [] for i in IDS}
    assert retry(gsr.fastSyncRead) == sdk.COMM_SUCCESS
    assert {i: gsr.getData(i, xl.PRESENT_POSITION, 4) for i in IDS} == goals


def test_bulk_read_of_two_addresses_and_fast_bulk_read(port) -> None:
    gbr = sdk.GroupBulkRead(port, PH)
    assert gbr.addParam(3, xl.PRESENT_POSITION, 4)
    assert gbr.addParam(11, xl.PRESENT_TEMPERATURE, 1)
    assert retry(gbr.txRxPacket) == sdk.COMM_SUCCESS
    pos = gbr.getData(3, xl.PRESENT_POSITION, 4)
    assert pos == retry(lambda: PH.read4ByteTxRx(port, 3, xl.PRESENT_POSITION))[0]
    assert gbr.getData(11, xl.PRESENT_TEMPERATURE, 1) == 32
    assert retry(gbr.fastBulkRead) == sdk.COMM_SUCCESS
    assert gbr.getData(3, xl.PRESENT_POSITION, 4) == pos
    assert gbr.getData(11, xl.PRESENT_TEMPERATURE, 1) == 32


def test_eeprom_write_with_torque_on_is_refused(port) -> None:
    assert retry(lambda: PH.write1ByteTxRx(port, 4, xl.TORQUE_ENABLE, 1)) == (sdk.COMM_SUCCESS, 0)
    before = retry(lambda: PH.read1ByteTxRx(port, 4, xl.RETURN_DELAY_TIME))[0]
    res, err = retry(lambda: PH.write1ByteTxRx(port, 4, xl.RETURN_DELAY_TIME, 100 - before % 100))
    assert (res, err) == (sdk.COMM_SUCCESS, dx2.ERR_ACCESS)
    assert retry(lambda: PH.read1ByteTxRx(port, 4, xl.RETURN_DELAY_TIME))[0] == before


def test_reboot_and_factory_reset(port) -> None:
    assert retry(lambda: PH.write1ByteTxRx(port, 6, xl.TORQUE_ENABLE, 1))[0] == sdk.COMM_SUCCESS
    assert retry(lambda: PH.reboot(port, 6)) == (sdk.COMM_SUCCESS, 0)
    time.sleep(0.05)
    assert retry(lambda: PH.read1ByteTxRx(port, 6, xl.TORQUE_ENABLE)) == (0, sdk.COMM_SUCCESS, 0)
    assert retry(lambda: PH.write1ByteTxRx(port, 7, xl.TORQUE_ENABLE, 0)) == (sdk.COMM_SUCCESS, 0)
    assert retry(lambda: PH.write1ByteTxRx(port, 7, xl.RETURN_DELAY_TIME, 10)) == \
        (sdk.COMM_SUCCESS, 0)
    assert retry(lambda: PH.factoryReset(port, 7, dx2.RESET_EXCEPT_ID_BAUD)) == \
        (sdk.COMM_SUCCESS, 0)
    time.sleep(0.05)
    assert retry(lambda: PH.read1ByteTxRx(port, 7, xl.RETURN_DELAY_TIME)) == \
        (250, sdk.COMM_SUCCESS, 0)
    assert retry(lambda: PH.clearMultiTurn(port, 7)) == (sdk.COMM_SUCCESS, 0)


def test_bad_crc_gets_no_reply_and_stuffing_round_trips(port) -> None:
    bad = bytearray(dx2.read(2, xl.PRESENT_POSITION, 4))
    bad[-1] ^= 0xFF
    port.clearPort()
    os.write(port.ser.fileno(), bytes(bad))
    time.sleep(0.1)
    assert not port.readPort(64)
    # 0x00FDFFFF: on the wire FF FF FD is followed by a stuffed FD; it must come back intact
    assert retry(lambda: PH.write1ByteTxRx(port, 2, xl.TORQUE_ENABLE, 0)) == (sdk.COMM_SUCCESS, 0)
    assert retry(lambda: PH.write1ByteTxRx(port, 2, xl.OPERATING_MODE, xl.MODE_EXTENDED_POSITION)) \
        == (sdk.COMM_SUCCESS, 0)
    assert dx2.write(2, xl.HOMING_OFFSET, (0xFDFFFF).to_bytes(4, "little")).count(b"\xfd\xfd") == 1
    value = int.from_bytes(b"\xff\xff\xfd\xff", "little", signed=True)
    assert retry(lambda: PH.write4ByteTxRx(port, 2, xl.HOMING_OFFSET, value & 0xFFFFFFFF)) == \
        (sdk.COMM_SUCCESS, 0)
    got, res, err = retry(lambda: PH.read4ByteTxRx(port, 2, xl.HOMING_OFFSET))
    assert (got, res, err) == (value & 0xFFFFFFFF, sdk.COMM_SUCCESS, 0)
