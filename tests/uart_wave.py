"""Test helper: a servo line's bursts drawn as a logic analyser would sample them (UART 8N1,
idle high; optionally a direction channel, high while the master drives), written as a raw
dump and made a sigrok session file by sigrok-cli (its own ``.sr`` writer, not ours)."""
from __future__ import annotations

import subprocess
from pathlib import Path
from typing import Iterable

import numpy as np

DATA_BIT, DIRECTION_BIT = 0, 2


def samples(bursts: Iterable[tuple[int, str, bytes]], baud: int, rate_hz: int,
            direction: bool = False, tail_us: int = 200) -> np.ndarray:
    """One uint8 a sample: bit 0 the line, bit 2 the direction pin (when ``direction``)."""
    bursts = list(bursts)
    spb = rate_hz / baud
    end_us = max(t + len(d) * 10e6 / baud for t, _, d in bursts) + tail_us
    n = int(end_us * rate_hz / 1e6) + 1
    line = np.ones(n, dtype=np.uint8)
    pin = np.zeros(n, dtype=np.uint8)
    for t_us, who, data in bursts:
        start = t_us * rate_hz / 1e6
        if who == "tx":
            pin[int(round(start)):int(round(start + len(data) * 10 * spb))] = 1
        for i, byte in enumerate(data):
            bits = [0] + [(byte >> k) & 1 for k in range(8)] + [1]
            for k, level in enumerate(bits):
                a = int(round(start + (i * 10 + k) * spb))
                b = int(round(start + (i * 10 + k + 1) * spb))
                line[a:b] = level
    out = line << DATA_BIT
    if direction:
        out |= pin << DIRECTION_BIT
    return out


def write_sr(path: Path, wave: np.ndarray, rate_hz: int, channels: int = 3) -> Path:
    """The samples through ``sigrok-cli -I binary`` into a ``.sr`` file."""
    raw = path.with_suffix(".bin")
    raw.write_bytes(wave.astype(np.uint8).tobytes())
    subprocess.run(["sigrok-cli", "-I", f"binary:numchannels={channels}:samplerate={rate_hz}",
                    "-i", str(raw), "-o", str(path)], check=True, capture_output=True)
    raw.unlink()
    return path
