"""How the ``status_*`` faults change one servo's status packet (hil/servobus/faults.py
``status_bursts`` says which are active and when): in the layout of the line's Dynamixel
protocol, the checksum made anew where only the content is wrong."""
from __future__ import annotations

from hil.scenario.faults_section import FaultEntry, FaultKind
from protocol.dynamixel import v2 as dx2


def mangled(kind: FaultKind, e: FaultEntry, data: bytearray, protocol: int) -> bytearray:
    """``data``, a status packet of Dynamixel ``protocol`` 1 or 2, as ``kind`` mangles it."""
    return _mangled(kind, e, data) if protocol == 1 else _mangled2(kind, e, data)


def _mangled(kind: FaultKind, e: FaultEntry, data: bytearray) -> bytearray:
    """A Protocol 1.0 status packet (FF FF ID LEN ERR P.. CHK) as ``kind`` mangles it."""
    if len(data) < 6:
        return data
    if kind is FaultKind.STATUS_CHECKSUM:
        data[-1] ^= 0xFF
        return data
    if kind is FaultKind.STATUS_TRUNCATED:
        return data[:-1]
    if kind is FaultKind.STATUS_WRONG_ID:
        data[2] = e.as_id
    elif kind is FaultKind.STATUS_ERROR:
        data[4] |= e.bits
    elif kind is FaultKind.STATUS_PADDED:
        data[-1:-1] = b"\x00"
        data[3] += 1
    data[-1] = (~sum(data[2:-1])) & 0xFF
    return data


def _mangled2(kind: FaultKind, e: FaultEntry, data: bytearray) -> bytearray:
    """A Protocol 2.0 status packet (FF FF FD 00 ID LEN_L LEN_H 55 ERR P.. CRC_L CRC_H) as
    ``kind`` mangles it; the CRC-16 made anew over what it covers, except for a wrong one.
    A Fast Sync/Bulk Read's one reply is mangled the same way: its first servo's error
    byte, its last CRC."""
    if len(data) < 11:
        return data
    if kind is FaultKind.STATUS_CHECKSUM:
        data[-1] ^= 0xFF
        return data
    if kind is FaultKind.STATUS_TRUNCATED:
        return data[:-1]
    if kind is FaultKind.STATUS_WRONG_ID:
        data[4] = e.as_id
    elif kind is FaultKind.STATUS_ERROR:
        data[8] |= e.bits
    elif kind is FaultKind.STATUS_PADDED:
        data[-2:-2] = b"\x00"
        length = (data[5] | data[6] << 8) + 1
        data[5], data[6] = length & 0xFF, length >> 8
    crc = dx2.crc16(data, 0, len(data) - 2)
    data[-2], data[-1] = crc & 0xFF, crc >> 8
    return data
