"""How the ``status_*`` faults change one servo's status packet (hil/servobus/faults.py
``status_bursts`` says which are active and when): in the layout of the line's Dynamixel
protocol, the checksum made anew where only the content is wrong."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from hexhil.hil.scenario.faults_section import FaultEntry, FaultKind
from hexhil.protocol.dynamixel import v2 as dx2


@dataclass(frozen=True)
class _Layout:
    min_len: int        # the shortest status packet
    id_at: int
    length_at: int      # its length field, of length_bytes little-endian
    length_bytes: int
    error_at: int
    check_bytes: int    # the checksum's (1.0) or CRC's (2.0) bytes at the end
    check: Callable[[bytearray], bytes]   # that check made anew over what it covers


def _checksum(data: bytearray) -> bytes:
    return bytes(((~sum(data[2:-1])) & 0xFF,))


def _crc(data: bytearray) -> bytes:
    crc = dx2.crc16(data, 0, len(data) - 2)
    return bytes((crc & 0xFF, crc >> 8))


# 1.0: FF FF ID LEN ERR P.. CHK; 2.0: FF FF FD 00 ID LEN_L LEN_H 55 ERR P.. CRC_L CRC_H (a
# Fast Sync/Bulk Read's one reply is mangled the same way: its first servo's error byte,
# its last CRC)
LAYOUTS = {1: _Layout(6, 2, 3, 1, 4, 1, _checksum), 2: _Layout(11, 4, 5, 2, 8, 2, _crc)}


def mangled(kind: FaultKind, e: FaultEntry, data: bytearray, protocol: int) -> bytearray:
    """``data``, a status packet of Dynamixel ``protocol`` 1 or 2, as ``kind`` mangles it."""
    lay = LAYOUTS[protocol]
    if len(data) < lay.min_len:
        return data
    if kind is FaultKind.STATUS_CHECKSUM:
        data[-1] ^= 0xFF
        return data
    if kind is FaultKind.STATUS_TRUNCATED:
        return data[:-1]
    if kind is FaultKind.STATUS_WRONG_ID:
        data[lay.id_at] = e.as_id
    elif kind is FaultKind.STATUS_ERROR:
        data[lay.error_at] |= e.bits
    elif kind is FaultKind.STATUS_PADDED:
        data[-lay.check_bytes:-lay.check_bytes] = b"\x00"
        field = slice(lay.length_at, lay.length_at + lay.length_bytes)
        data[field] = (int.from_bytes(data[field], "little") + 1).to_bytes(lay.length_bytes,
                                                                            "little")
    data[-lay.check_bytes:] = lay.check(data)
    return data
