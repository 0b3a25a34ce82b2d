"""Dynamixel bytes decoded, one module a protocol, keyed by its version: v1.py, v2.py. Each
gives ``decode(data)`` (records for ``hexhil protocol decode``) and ``TracePackets`` (the
packets a serial burst completes, encoded for the trace's ``/serial``,
host_tools/trace/recorder.py)."""
from __future__ import annotations

from types import ModuleType

from host_tools.dynamixel.decode import v1, v2

DECODERS: dict[int, ModuleType] = {1: v1, 2: v2}


def guess_protocol(data: bytes) -> int:
    """2 when the bytes hold a Protocol 2.0 header (FF FF FD 00), else 1."""
    return 2 if v2.HEADER in data else 1
