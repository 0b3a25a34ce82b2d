"""bench/bench_protocol.py runs end to end at a tiny size (figures are never asserted)."""
from __future__ import annotations

import pytest

from bench import bench_protocol
from hexhil.protocol.dynamixel import v1 as dxl


def test_bus_capture_is_what_the_note_says() -> None:
    data = bench_protocol.bus_capture(10)
    packets = dxl.Parser().feed(data)
    assert len(packets) == 10 * 37
    assert sum(p.code == dxl.SYNC_WRITE for p in packets) == 10
    assert sum(p.code == dxl.READ and p.id != dxl.BROADCAST_ID for p in packets) == 10 * 18


def test_rows_from_both_interpreters(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(bench_protocol, "CYCLES", 4)
    monkeypatch.setattr(bench_protocol, "CAN_ROUNDS", 50)
    rows = bench_protocol.run()
    names = [r.name for r in rows]
    assert any("parser CPython" in n for n in names)
    assert any("parser MicroPython" in n for n in names)
    assert any("CAN" in n and "MicroPython" in n for n in names)
    assert all(r.value > 0 for r in rows)
    assert rows[0].unit == "bytes/s" and "148 packets" in rows[0].note
