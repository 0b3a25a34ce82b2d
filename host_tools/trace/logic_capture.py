"""A logic analyser's capture of a UART line: sigrok's session files (``.sr``) read, the
line's baud found from its edges, and its bytes decoded with their times.

A ``.sr`` file (libsigrok's "srzip", the format PulseView and ``sigrok-cli -o x.sr``
write) is a zip holding ``version`` (2), ``metadata`` (INI: a ``[device 1]`` section with
``samplerate`` such as ``8 MHz``, ``total probes``, ``probeN`` names, ``unitsize`` bytes a
sample, ``capturefile`` the samples' base name) and the samples in files named
``capturefile`` or ``capturefile-1``, ``-2``...: each sample ``unitsize`` bytes little
endian, bit N-1 the level of probe N. Read here with the zip and INI readers of the
standard library: nothing of libsigrok's is needed to import one.

UART framing is the Dynamixel line's: idle high, a start bit, 8 data bits LSB first, one
stop bit. Every byte is sampled at the middle of its bits; one whose stop bit is low is a
framing error (a collision on a half-duplex line, or the wrong baud).
"""
from __future__ import annotations

import bisect
import configparser
import re
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hexhil.protocol.dynamixel import ax12, xl430
from hexhil.protocol.errors import BadFile, BadValue

# the rates a Dynamixel line runs at: the X series' register values and the AX-12's usual
STANDARD_BPS = tuple(sorted(set(xl430.BAUD_BPS) | {19_200, 38_400, 200_000, 250_000,
                                                    400_000, 500_000}))
MIN_SAMPLES_PER_BIT = 3.0   # below it a mid-bit sample can land on the next bit
BITS_PER_BYTE = 10          # start, 8 data, stop
_RATE = re.compile(r"^\s*([0-9]+(?:\.[0-9]+)?)\s*([kMG]?)Hz\s*$", re.IGNORECASE)
_SCALE = {"": 1, "k": 1_000, "m": 1_000_000, "g": 1_000_000_000}


@dataclass(frozen=True)
class LogicCapture:
    """Samples of a few logic channels at one rate."""

    path: str
    samplerate_hz: int
    channels: tuple[str, ...]       # probe names, bit 0 first
    samples: np.ndarray             # one unsigned integer a sample, bit i = channels[i]

    def channel(self, name_or_index: str | int) -> int:
        """The bit of a channel given by its name, or its number counted from 0."""
        if isinstance(name_or_index, str) and name_or_index in self.channels:
            return self.channels.index(name_or_index)
        try:
            i = int(name_or_index)
        except (TypeError, ValueError):
            i = -1
        if not 0 <= i < len(self.channels):
            raise BadValue(f"{self.path}: no channel {name_or_index!r} (channels: "
                           f"{', '.join(self.channels)})")
        return i

    def levels(self, bit: int) -> np.ndarray:
        """One channel's levels, 0 or 1, a uint8 per sample."""
        return ((self.samples >> bit) & 1).astype(np.uint8)


def parse_samplerate(text: str) -> int:
    """``8 MHz``, ``250 kHz``, ``100 Hz`` (sigrok's way of writing a rate) -> Hz."""
    m = _RATE.match(text)
    if not m:
        raise ValueError(f"samplerate {text!r}")
    return int(round(float(m.group(1)) * _SCALE[m.group(2).lower()]))


def read_sr(path: str | Path) -> LogicCapture:
    """A sigrok session file's logic samples (the module docstring says the format)."""
    path = Path(path)
    try:
        zf = zipfile.ZipFile(path)
    except FileNotFoundError:
        raise BadFile(f"{path}: no such capture file") from None
    except (zipfile.BadZipFile, OSError) as exc:
        raise BadValue(f"{path}: not a sigrok session (.sr) file, or truncated: "
                       f"{str(exc) or exc.__class__.__name__}") from None
    with zf:
        names = set(zf.namelist())
        if "metadata" not in names:
            raise BadValue(f"{path}: not a sigrok session file (no metadata in the zip)")
        text = _member(zf, "metadata", path).decode("ascii", errors="replace")
        try:
            meta = configparser.ConfigParser(interpolation=None, strict=False)
            meta.read_string(text)
            dev = meta["device 1"]
            rate = parse_samplerate(dev.get("samplerate", ""))
            unit = int(dev.get("unitsize", "1"))
            total = int(dev.get("total probes", "0"))
            base = dev.get("capturefile", "logic-1")
        except (configparser.Error, KeyError, ValueError) as exc:
            raise BadValue(f"{path}: unreadable sigrok metadata ({_line(exc)})") from None
        if rate <= 0 or unit not in (1, 2, 4, 8) or not 0 < total <= 8 * unit:
            raise BadValue(f"{path}: sigrok metadata says samplerate {rate} Hz, unitsize "
                           f"{unit}, {total} probes: not a logic capture this reads")
        channels = tuple(dev.get(f"probe{i + 1}", str(i)) for i in range(total))
        chunks = sorted((int(n[len(base) + 1:]), n) for n in names
                        if n.startswith(base + "-") and n[len(base) + 1:].isdigit())
        files = [n for _, n in chunks] or ([base] if base in names else [])
        if not files:
            raise BadValue(f"{path}: no logic samples ({base}) in the capture")
        raw = b"".join(_member(zf, n, path) for n in files)
    if len(raw) % unit:
        raise BadValue(f"{path}: truncated capture: {len(raw)} bytes of samples is no whole "
                       f"number of {unit}-byte samples")
    if not raw:
        raise BadValue(f"{path}: the capture holds no samples")
    dtype = {1: "<u1", 2: "<u2", 4: "<u4", 8: "<u8"}[unit]
    return LogicCapture(str(path), rate, channels, np.frombuffer(raw, dtype=dtype))


def _line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else exc.__class__.__name__


def _member(zf: zipfile.ZipFile, name: str, path: Path) -> bytes:
    """One file of the zip; a damaged one (a CRC, a deflate stream, a header cut short)
    is the capture's one-line error."""
    try:
        return zf.read(name)
    except (zipfile.BadZipFile, EOFError, OSError, zlib.error, NotImplementedError,
            ValueError) as exc:
        raise BadValue(f"{path}: truncated or damaged capture ({name}: {_line(exc)})") from None


def edges(levels: np.ndarray) -> np.ndarray:
    """Sample indexes where the level changes (the first sample of the new level)."""
    return np.flatnonzero(np.diff(levels)) + 1


def measure_bps(capture: LogicCapture, bit: int) -> float:
    """The line's bit rate from its pulse widths: the shortest pulses (but the shortest
    1 %: glitches) are one bit, and every pulse inside a byte is a whole number of bits."""
    e = edges(capture.levels(bit))
    if len(e) < 4:
        raise BadValue(f"{capture.path}: channel {capture.channels[bit]} hardly changes "
                       f"({len(e)} edges): no serial traffic to find the baud from")
    widths = np.diff(e).astype(np.float64)
    shortest = float(np.sort(widths)[len(widths) // 100])   # a glitch or two left out
    one = widths[widths < 1.5 * shortest]
    spb = float(np.mean(one))
    inside = widths[widths <= (BITS_PER_BYTE - 1) * spb + spb / 2]
    k = np.round(inside / spb)
    spb = float(np.sum(inside) / np.sum(k))
    return capture.samplerate_hz / spb


def find_baud(capture: LogicCapture, bit: int) -> int:
    """The standard Dynamixel rate the line runs at, within the servo's tolerance (3 %)."""
    bps = measure_bps(capture, bit)
    best = min(STANDARD_BPS, key=lambda b: abs(b - bps))
    if capture.samplerate_hz / best < MIN_SAMPLES_PER_BIT:
        raise BadValue(f"{capture.path}: sample rate {capture.samplerate_hz} Hz is too low for "
                       f"a {best} bit/s line (at least {MIN_SAMPLES_PER_BIT:g} samples a bit): "
                       "capture at a higher rate")
    if abs(best - bps) > ax12.BAUD_TOLERANCE * best:
        raise BadValue(f"{capture.path}: baud not found: the pulses measure {bps:.0f} bit/s at "
                       f"the capture's {capture.samplerate_hz} Hz, within 3 % of no Dynamixel "
                       f"rate ({', '.join(map(str, STANDARD_BPS))}); is the sample rate right, "
                       "or give the baud in the map file")
    return best


@dataclass(frozen=True)
class UartByte:
    start_ns: int      # the start bit's falling edge
    value: int
    framing_ok: bool   # the stop bit was high


def decode_uart(capture: LogicCapture, bit: int, bps: int) -> list[UartByte]:
    """Every byte on one channel at ``bps`` (8N1, idle high), in order."""
    spb = capture.samplerate_hz / bps
    if spb < MIN_SAMPLES_PER_BIT:
        raise BadValue(f"{capture.path}: sample rate {capture.samplerate_hz} Hz is too low for "
                       f"{bps} bit/s (at least {MIN_SAMPLES_PER_BIT:g} samples a bit)")
    lv = capture.levels(bit)
    n = len(lv)
    falls = np.flatnonzero((lv[1:] == 0) & (lv[:-1] == 1)) + 1
    if lv[0] == 0:
        falls = np.concatenate(([0], falls))
    mids = np.round((np.arange(BITS_PER_BYTE) + 0.5) * spb).astype(np.int64)
    weights = 1 << np.arange(8)
    last = n - 1 - int(mids[-1])   # the last sample a whole byte can start on
    skip = int(round((BITS_PER_BYTE - 0.5) * spb))   # a byte's start to the next's earliest
    # where bytes start, in order: each falling edge not inside the byte before, whose
    # start bit is still low at its middle (else a glitch); then every byte read at once
    edges_at, levels, mid0 = falls.tolist(), lv.tobytes(), int(mids[0])
    starts: list[int] = []
    i, count = 0, len(edges_at)
    while i < count:
        f = edges_at[i]
        if f > last:
            break    # the capture ends inside this byte
        if levels[f + mid0]:
            i += 1
            continue
        starts.append(f)
        i = bisect.bisect_left(edges_at, f + skip, i)
    if not starts:
        return []
    at = np.asarray(starts, dtype=np.int64)
    bits = lv[at[:, None] + mids[None, :]]
    values = bits[:, 1:9].astype(np.int64) @ weights
    ns = np.round(at * (1e9 / capture.samplerate_hz)).astype(np.int64)
    return [UartByte(t, v, ok) for t, v, ok in
            zip(ns.tolist(), values.tolist(), (bits[:, 9] == 1).tolist())]
