"""The servo line's bytes as one stream, as the run's serial digest takes them: a record
per ``on_bytes`` call, u64 t_us and u8 'T' (master to servos) or 'R' (servos to master),
then the bytes; the records' lengths beside it. The compiled status reads
(hil/servobus/status_reads.py) hand a return's records over in one call to an ``on_bytes``
that takes a stream (the run's digest and recorder, hil/run/core.py): six calls a cycle
were about a tenth of an in-process run's overhead."""
from __future__ import annotations

import struct
from typing import Iterator, Protocol, Sequence

HEAD = struct.Struct("<QB")   # a record's head: t_us, 'T' or 'R'
TX, RX = 0x54, 0x52


class OnBytesStream(Protocol):
    """A bus's ``on_bytes`` (t_us, "tx"/"rx", data) that also takes many records at once,
    in order, as if each were a call."""

    def __call__(self, t_us: int, direction: str, data: bytes) -> None: ...
    def stream(self, stream: bytes, lens: Sequence[int]) -> None: ...


def head(t_us: int, direction: str) -> bytes:
    return HEAD.pack(t_us, TX if direction == "tx" else RX)


def records(stream: bytes, lens: Sequence[int]) -> Iterator[tuple[int, str, bytes]]:
    """The stream's records as ``on_bytes`` takes them: (t_us, "tx" or "rx", data)."""
    at = 0
    for n in lens:
        t_us, d = HEAD.unpack_from(stream, at)
        at += HEAD.size
        yield t_us, "tx" if d == TX else "rx", stream[at:at + n]
        at += n


def last_t_us(stream: bytes, lens: Sequence[int]) -> int:
    """The last record's time."""
    return HEAD.unpack_from(stream, len(stream) - HEAD.size - lens[-1])[0]
