"""The servo line's bytes as one stream (hil/servobus/serial_stream.py): the compiled
reads hand a return's records over in one call, and the run's digest and the recorder
must come out as if each record had been its own ``on_bytes`` call."""
from __future__ import annotations

import random
import struct
from pathlib import Path

import pytest
from mcap.reader import make_reader

from hexhil.hil.run.core import SerialTap
from hexhil.hil.servobus import serial_stream
from hexhil.trace import recorder as rec
from hexhil.trace import topics
from hexhil.protocol.dynamixel import v1 as dynamixel

WINDOW_US = 50_000


def _traffic(seed: int, n: int) -> list[tuple[int, str, bytes]]:
    """READs and their status packets, some split and some garbled, at rising times."""
    rnd = random.Random(seed)
    out, t = [], 0
    for _ in range(n):
        sid = rnd.randint(1, 18)
        pkt = dynamixel.read(sid, 36, 2)
        st = dynamixel.status(sid, 0, bytes((rnd.randrange(256), rnd.randrange(4))))
        t += rnd.randint(1, 3000)
        out.append((t, "tx", pkt))
        t += 80 + rnd.randint(0, 600)
        if rnd.random() < 0.2:
            st = bytes(b ^ rnd.randrange(1, 256) if rnd.random() < 0.3 else b for b in st)
        out.append((t, "rx", st))
    return out


def _stream(records: list[tuple[int, str, bytes]]) -> tuple[bytes, list[int]]:
    return (b"".join(serial_stream.head(t, d) + data for t, d, data in records),
            [len(data) for _, _, data in records])


def _groups(records: list, seed: int) -> list[list]:
    rnd = random.Random(seed)
    out, at = [], 0
    while at < len(records):
        k = rnd.randint(1, 8)
        out.append(records[at:at + k])
        at += k
    return out


def test_records_round_trip() -> None:
    records = _traffic(1, 40)
    stream, lens = _stream(records)
    assert list(serial_stream.records(stream, lens)) == records
    assert serial_stream.last_t_us(stream, lens) == records[-1][0]
    # the head is what the digest takes of one call: u64 time, 'T' or 'R'
    assert serial_stream.head(7, "tx") == struct.pack("<QB", 7, ord("T"))
    assert serial_stream.head(7, "rx") == struct.pack("<QB", 7, ord("R"))


@pytest.mark.parametrize("seed", [2, 3])
def test_tap_stream_is_its_calls(seed: int) -> None:
    """The digest (and what the recorder is told, in order) is the same either way."""
    class Calls:
        def __init__(self) -> None:
            self.seen: list = []

        def serial(self, t_us: int, direction: str, data: bytes) -> None:
            self.seen.append((t_us, direction, bytes(data)))

        def serial_stream(self, stream: bytes, lens: list[int]) -> None:
            self.seen.extend(serial_stream.records(stream, lens))

    records = _traffic(seed, 60)
    one, many = SerialTap(Calls()), SerialTap(Calls())   # type: ignore[arg-type]
    for t, d, data in records:
        one(t, d, data)
    for group in _groups(records, seed):
        many.stream(*_stream(group))
    assert one.digest.hexdigest() == many.digest.hexdigest()
    assert one.recorder.seen == many.recorder.seen == records   # type: ignore[union-attr]
    moved = list(records)
    moved[5] = (moved[5][0] + 1,) + moved[5][1:]   # one record a microsecond later
    other = SerialTap(None)
    other.stream(*_stream(moved))
    assert other.digest.hexdigest() != one.digest.hexdigest()


@pytest.mark.parametrize("encode_in", list(rec.EncodeIn))
def test_recorder_stream_is_its_calls(tmp_path: Path, encode_in: rec.EncodeIn) -> None:
    """A trace whose bytes came as streams, some of them across a window's end, is the
    file the same bytes make one call each."""
    records = _traffic(4, 300)
    groups = _groups(records, 4)
    assert any(g[0][0] // WINDOW_US != g[-1][0] // WINDOW_US for g in groups)
    paths = {}
    for way in ("calls", "streams"):
        paths[way] = tmp_path / f"{way}.mcap"
        r = rec.Recorder(paths[way], {"seed": 4}, flush_interval_us=WINDOW_US,
                         encode_in=encode_in)
        for group in groups:
            if way == "calls":
                for t, d, data in group:
                    r.serial(t, d, data)
            else:
                r.serial_stream(*_stream(group))
            r.can(group[-1][0], 0x700, b"\x01")   # something else between the streams
        r.close()
    assert paths["calls"].read_bytes() == paths["streams"].read_bytes()
    with paths["streams"].open("rb") as f:
        serial = [m for _, _, m in make_reader(f).iter_messages(topics=[topics.T_SERIAL])]
    assert [m.log_time // 1000 for m in serial] == [t for t, _, _ in records]
