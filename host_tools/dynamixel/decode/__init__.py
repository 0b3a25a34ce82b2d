"""Dynamixel bytes decoded, one module a protocol, keyed by its version: v1.py, v2.py. Each
gives ``decode(data)`` (records for ``hexhil protocol decode``) and ``TracePackets`` (the
packets a serial burst completes, encoded for the trace's ``/serial``,
host_tools/trace/recorder.py)."""
from __future__ import annotations

from types import ModuleType

from hexhil.dynamixel.decode import v1, v2
from hexhil.protocol.dynamixel import v1 as dx1
from hexhil.protocol.dynamixel import v2 as dx2

DECODERS: dict[int, ModuleType] = {1: v1, 2: v2}


def guess_protocol(data: bytes) -> int:
    """2 when the bytes hold a Protocol 2.0 header (FF FF FD 00), else 1."""
    return 2 if v2.HEADER in data else 1


def packet_spans(data: bytes, protocol: int) -> list[tuple[int, int, bool]]:
    """``(offset, length, status)`` of each whole packet in ``data``, in order, read in
    ``protocol`` (``status``: Protocol 2.0's instruction 0x55; Protocol 1.0's packets do
    not say, and are all False). A packet ends where the bytes the parser still holds
    begin: one inside a rejected header's length is found with the bytes after it held."""
    out = []
    if protocol == 2:
        p = dx2.Parser()
        for i, b in enumerate(data):
            if p.push(b):
                end = i + 1 - p.pending()
                out.append((end - p.raw_len, p.raw_len, p.current().instr == dx2.STATUS))
    else:
        p1 = dx1.Parser()
        for i, b in enumerate(data):
            if p1.push(b):
                n = dx1.PARAMS_OFFSET + p1.nparams + 1
                out.append((i + 1 - p1.pending() - n, n, False))
    return out
