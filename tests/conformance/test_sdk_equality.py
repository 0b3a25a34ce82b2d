"""Byte-for-byte equality with the official dynamixel_sdk PacketHandler(1.0).

The SDK writes through ``ScriptedPort``; our builders must produce the same bytes, and the
SDK must accept the status packets our ``status()`` builds in reply.
"""
from __future__ import annotations

import dynamixel_sdk as sdk
import pytest

from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl

from .sdk_port import ScriptedPort

PH = sdk.PacketHandler(1.0)


def test_ping_is_ping_then_model_number_read() -> None:
    table = {7: bytes(ax12.defaults())}
    port = ScriptedPort(table)
    model, result, error = PH.ping(port, 7)
    assert (result, error) == (sdk.COMM_SUCCESS, 0)
    assert model == ax12.MODEL_NUMBER  # decoded by the SDK from our status packet
    assert port.written == [dxl.ping(7), dxl.read(7, 0, 2)]


@pytest.mark.parametrize("dev_id, address, length", [(1, 43, 1), (12, ax12.PRESENT_POSITION, 2),
                                                      (253, 0, 50)])
def test_read(dev_id: int, address: int, length: int) -> None:
    table = bytes(range(50))
    port = ScriptedPort({dev_id: table})
    data, result, error = PH.readTxRx(port, dev_id, address, length)
    assert result == sdk.COMM_SUCCESS and data == list(table[address:address + length])
    assert port.written == [dxl.read(dev_id, address, length)]


def test_read_reports_our_error_bits() -> None:
    port = ScriptedPort(error=dxl.ERR_OVERHEATING | dxl.ERR_OVERLOAD)
    _, result, error = PH.read1ByteTxRx(port, 3, ax12.PRESENT_TEMPERATURE)
    assert result == sdk.COMM_SUCCESS
    assert dxl.error_names(error) == ["overheating", "overload"]


@pytest.mark.parametrize("dev_id, value", [(1, 1), (5, 0), (0, 255)])
def test_write_1_byte(dev_id: int, value: int) -> None:
    port = ScriptedPort()
    assert PH.write1ByteTxRx(port, dev_id, ax12.TORQUE_ENABLE, value) == (sdk.COMM_SUCCESS, 0)
    assert port.written == [dxl.write(dev_id, ax12.TORQUE_ENABLE, bytes((value,)))]


@pytest.mark.parametrize("dev_id, value", [(1, 512), (18, 0), (4, 1023), (9, 0x3FF | 0x400)])
def test_write_2_bytes(dev_id: int, value: int) -> None:
    port = ScriptedPort()
    assert PH.write2ByteTxRx(port, dev_id, ax12.GOAL_POSITION, value) == (sdk.COMM_SUCCESS, 0)
    assert port.written == [dxl.write(dev_id, ax12.GOAL_POSITION, value.to_bytes(2, "little"))]


def test_reg_write_and_action() -> None:
    port = ScriptedPort()
    data = [0x00, 0x02, 0x40, 0x01]
    assert PH.regWriteTxRx(port, 6, ax12.GOAL_POSITION, 4, data) == (sdk.COMM_SUCCESS, 0)
    assert PH.regWriteTxOnly(port, 7, ax12.GOAL_POSITION, 4, data) == sdk.COMM_SUCCESS
    assert PH.action(port, dxl.BROADCAST_ID) == sdk.COMM_SUCCESS
    assert port.written == [dxl.reg_write(6, ax12.GOAL_POSITION, bytes(data)),
                            dxl.reg_write(7, ax12.GOAL_POSITION, bytes(data)),
                            dxl.action()]
    assert dxl.action() == bytes.fromhex("FFFFFE0205FA")


def test_factory_reset() -> None:
    port = ScriptedPort()
    assert PH.factoryReset(port, 3) == (sdk.COMM_SUCCESS, 0)
    assert port.written == [dxl.factory_reset(3)]


def test_group_sync_write_position_and_speed_to_18_servos() -> None:
    port = ScriptedPort()
    group = sdk.GroupSyncWrite(port, PH, ax12.GOAL_POSITION, 4)
    entries = []
    for dev_id in range(1, 19):
        position = (dev_id * 97) % 1024
        speed = 100 + 50 * dev_id
        data = [sdk.DXL_LOBYTE(position), sdk.DXL_HIBYTE(position),
                sdk.DXL_LOBYTE(speed), sdk.DXL_HIBYTE(speed)]
        assert group.addParam(dev_id, data)
        entries.append((dev_id, bytes(data)))
    assert group.txPacket() == sdk.COMM_SUCCESS
    ours = dxl.sync_write(ax12.GOAL_POSITION, 4, entries)
    assert port.written == [ours]
    assert len(ours) == 98  # the reference notes' 98 bytes = 0.98 ms at 1 Mbps
