"""The coverage-guided fuzz targets: each one's ``one_input(data: bytes)``, code, seeds, words.

Each ``one_input`` turns libFuzzer's bytes into a hostile input, runs it, and raises on any
broken invariant (``Broken``) or on any exception the code under test lets out; a refusal the
code promises (``UserError``, ``ValueError`` from the CAN codecs) is not a crash. The same
functions replay an input without atheris (``fuzz/cov.py`` minimises a crash with them,
``tests/test_fuzz.py`` keeps the inputs found), so this module imports nothing from atheris.
"""
from __future__ import annotations

import atexit
import math
import random
import shutil
import struct
import tempfile
from pathlib import Path
from typing import Any, Callable

import cantools

from fuzz import fuzz_bus, fuzz_v2_bus, fuzz_can, fuzz_elf, fuzz_logs, fuzz_trace
from fuzz.hostile import GAP_US, Rng, garbage
from hexhil.hil import scenario
from hexhil.hil.mcu.elf_image import load_elf
from hexhil.hil.servobus.faults import Faults
from hexhil.trace import reader, recover
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol import can_frames as cf
from hexhil.protocol.dynamixel import v1 as dxl
from hexhil.protocol.dynamixel import v2 as dx2
from hexhil.protocol.errors import UserError

ROOT = Path(__file__).resolve().parent.parent
_SCRATCH: list[Path] = []


def scratch() -> Path:
    """This process's folder for the files a target writes (one per process, reused by
    every input; under the fuzzer, inside the runner's TMPDIR, which the runner removes)."""
    if not _SCRATCH:
        _SCRATCH.append(Path(tempfile.mkdtemp(prefix="hexhil-cov-")))
        atexit.register(shutil.rmtree, _SCRATCH[0], True)
    return _SCRATCH[0]


class Broken(Exception):
    """An invariant the target checks did not hold (a crash, as an escape would be)."""


def _resync(p: Any, data: bytes, want: bytes, max_packet: int,
            reported: Callable[[Any, bytes, int], bytes]) -> None:
    """Push ``data`` as garbage on the line, then (after a gap over the inter-byte timeout)
    ``want``, which the parser ``p`` must find again. ``reported(p, stream, i)`` gives the
    bytes of the packet the parser completed at ``stream[i]``, raising Broken if wrong."""
    stream = bytes(data) + want
    t = 0
    found = False
    for i, b in enumerate(stream):
        if i == len(data):
            t += GAP_US
        t += 10
        if p.push(b, t):
            raw = reported(p, stream, i)
            found = i >= len(data) and raw == want
        if p.pending() > max_packet:
            raise Broken(f"parser holds {p.pending()} bytes")
    if not found:
        raise Broken(f"no resync: {want.hex()} after the garbage was not found")


# --- the Protocol 1.0 stream parser --------------------------------------------------------
def _reported(p: dxl.Parser, stream: bytes, i: int) -> bytes:
    """The packet in the parser's buffer: whole, a right checksum, in what was sent."""
    raw = bytes(p.buf[0:dxl.PARAMS_OFFSET + p.nparams + 1])
    if dxl.checksum(raw, 2, len(raw) - 1) != raw[-1] or raw[3] != p.nparams + 2:
        raise Broken(f"parser reported a bad packet {raw.hex()}")
    if raw not in stream:
        raise Broken(f"parser reported bytes never sent {raw.hex()}")
    return raw


def parser_one_input(data: bytes) -> None:
    """The bytes as garbage on the line, then one valid packet the parser must find again
    (``_resync``); every packet it reports must be whole, with a right checksum, and lie in
    what was sent, and so must what a flush at the end rescans."""
    want = dxl.packet(len(data) % 0xFE, data[0] if data else dxl.PING, data[-3:])
    sent = bytes(data)
    _resync(dxl.Parser(), sent, want, dxl.MAX_PACKET, _reported)
    rest = dxl.Parser()
    rest.feed(data)
    for pkt in rest.flush():  # a host decoding a capture: rescans a partial packet
        if pkt.raw not in sent:
            raise Broken(f"flush reported bytes never sent {pkt.raw.hex()}")


def parser_seeds() -> list[bytes]:
    rng = Rng(7)
    return [b"", dxl.ping(1), dxl.read(3, 36, 2), dxl.sync_write(30, 2, [(1, b"\x00\x02")]),
            b"\xff\xff\xff\x01\x02\x01\xfb", *(bytes(garbage(rng)) for _ in range(12))]


# --- the CAN frame codecs -------------------------------------------------------------------
_DB: list[cantools.database.can.Database] = []
_IDS = sorted(cf.BY_ID)


def can_one_input(data: bytes) -> None:
    """Byte 0 picks a frame (or a stranger ID), the rest is its payload and then doubles
    to encode. Decoding agrees with cantools and protocol/hexhil.dbc or refuses with
    ValueError; re-encoding gives cantools' bytes; encoding any value gives the frame's
    bytes or ValueError."""
    if not _DB:
        _DB.append(cantools.database.load_file(str(fuzz_can.DBC)))
    if not data:
        return
    k = data[0]
    arb_id = _IDS[k % len(_IDS)] if k < 0xF0 else (k << 3 | (len(data) & 7)) & 0x7FF
    payload = data[1:9]
    try:
        name, ours = cf.decode(arb_id, payload)
    except ValueError:
        if arb_id in cf.BY_ID and len(payload) >= cf.DLC[cf.BY_ID[arb_id]]:
            raise Broken(f"decode refused a whole frame 0x{arb_id:03X} {payload.hex()}")
        return
    dlc = cf.DLC[name]
    theirs = _DB[0].decode_message(arb_id, payload[:dlc], decode_choices=False)
    if not (ours.keys() == theirs.keys() and all(
            math.isclose(ours[s], theirs[s], rel_tol=1e-9, abs_tol=1e-12) for s in ours)):
        raise Broken(f"{name} {payload.hex()}: ours {ours} cantools {dict(theirs)}")
    sigs = cf.FRAMES[name][2]
    if all(s[1] != cf.ENUM or s[3] <= ours[s[0]] <= s[4] for s in sigs):
        again = cf.encode(name, **ours)[1]
        if _DB[0].encode_message(arb_id, ours) != again:
            raise Broken(f"{name} {payload.hex()}: re-encoded differently from cantools")
    tail = data[9:]
    values = {}
    for i, s in enumerate(sigs):
        chunk = tail[8 * i:8 * i + 8]
        values[s[0]] = struct.unpack("<d", chunk)[0] if len(chunk) == 8 else float(i)
    try:
        got_id, got = cf.encode(name, **values)
    except ValueError:
        return
    if got_id != arb_id or len(got) != dlc:
        raise Broken(f"{name}: encode gave 0x{got_id:03X} {got.hex()}")


def can_seeds() -> list[bytes]:
    rng = random.Random(3)
    out = []
    for i, arb_id in enumerate(_IDS):
        dlc = cf.DLC[cf.BY_ID[arb_id]]
        out.append(bytes((i,)) + bytes(dlc))
        out.append(bytes((i,)) + rng.randbytes(8) + struct.pack("<4d", 0.5, -1.0, 1e3, 2.0))
    return out


# --- the emulated bus with 18 servos ------------------------------------------------------
READS_US = (0, 200, fuzz_bus.READ_TIMEOUT_US)
MAX_OPS = 12


def _ops(data: bytes) -> list[tuple[int, bytes]]:
    """The bytes as up to MAX_OPS operations: (0, packet built with a right checksum),
    (1, raw bytes), (2, a read), (3, an idle gap)."""
    ops, i = [], 0
    while i < len(data) and len(ops) < MAX_OPS:
        op = data[i] & 3
        if op == 0 and i + 3 <= len(data):
            n = data[i] >> 2 & 15
            params = data[i + 3:i + 3 + n]
            ops.append((0, dxl.packet(data[i + 1] % 0xFF, data[i + 2], params)))
            i += 3 + n
        elif op == 1:
            n = data[i] >> 2
            ops.append((1, data[i + 1:i + 1 + n]))
            i += 1 + n
        else:
            ops.append((op if op != 0 else 1, bytes((data[i] >> 2,))))
            i += 1
    return ops


def bus_one_input(data: bytes) -> None:
    """A fresh bus of 18 AX-12s, then the operations; after them every register within its
    range, identity registers unchanged, and a PING answered once the line idled."""
    spec = fuzz_bus.AX12
    bus = spec.fresh_bus()
    for op, arg in _ops(data):
        if op in (0, 1):
            bus.master_write(arg)
            bus.master_read(spec.read_bytes, READS_US[len(arg) % 3])
        elif op == 2:
            bus.master_read(arg[0] * 4 + 1, READS_US[arg[0] % 3])
        else:
            bus.idle_until(bus.clock.t_us + arg[0] * 2_000)
    _after_stream(spec, bus)


def _after_stream(spec: fuzz_bus.BusSpec, bus: Any) -> None:
    """Every register within its range, identity registers unchanged, and a PING answered
    once the line idled (fuzz_bus.py's checks, raised as ``Broken``)."""
    broken = fuzz_bus.broken_servo(spec, bus)
    if broken:
        raise Broken(broken)
    target, answered = fuzz_bus.resync(spec, bus)
    if target is not None and not answered:
        raise Broken(f"no resync: servo {target.id} did not answer a PING")


def bus_seeds() -> list[bytes]:
    """Streams of well-formed instructions in the op encoding (op 0: len<<2, id, code)."""
    def pkt(dev_id: int, code: int, params: bytes) -> bytes:
        return bytes((len(params) << 2, dev_id, code)) + params
    return [
        pkt(1, dxl.PING, b""),
        pkt(2, dxl.READ, bytes((0, 50))) + b"\x02",
        pkt(3, dxl.WRITE, bytes((ax12.GOAL_POSITION, 0, 2))) + pkt(3, dxl.READ, bytes((36, 2))),
        pkt(4, dxl.REG_WRITE, bytes((ax12.MOVING_SPEED, 0xFF, 3))) + pkt(0xFE, dxl.ACTION, b""),
        pkt(0xFE, dxl.SYNC_WRITE, bytes((30, 2, 1, 0, 2, 2, 0, 1))),
        pkt(5, dxl.WRITE, bytes((ax12.TORQUE_ENABLE, 1))) + b"\x07" + pkt(5, dxl.READ, b"\x18\x01"),
        pkt(6, dxl.WRITE, bytes((ax12.ID, 9))) + pkt(9, dxl.PING, b""),
        b"\x05\xff\xff\x01\x03" + pkt(7, dxl.PING, b""),
    ]


# --- the MCAP reader and recover ------------------------------------------------------------
def trace_one_input(data: bytes) -> None:
    """The bytes as a trace file: reading, info and recover give a one-line UserError or
    work, and what recover writes reads back whole."""
    src, dst = scratch() / "mutant.mcap", scratch() / "recovered.mcap"
    src.write_bytes(data)
    for step, fn in (("read", lambda: fuzz_trace._read_all(src)),
                     ("info", lambda: reader.info(src)),
                     ("recover", lambda: recover.recover(src, dst, overwrite=True)),
                     ("read recovered", lambda: fuzz_trace._read_all(dst))):
        try:
            fn()
        except UserError as exc:
            if "\n" in str(exc):
                raise Broken(f"{step}: UserError over several lines: {exc!r}") from None
            if step == "recover":
                return
            if step == "read recovered":
                raise Broken(f"recover wrote a file that does not read: {exc}") from None


def trace_seeds() -> list[bytes]:
    """A real small trace (every kind of record the recorder writes), and its first half,
    as a killed writer leaves it."""
    whole = fuzz_trace.sample_trace(scratch() / "seed.mcap", seconds=1)
    return [whole, whole[:len(whole) // 2]]


# --- the TOML scenario loader ---------------------------------------------------------------
def scenario_one_input(data: bytes) -> None:
    """The bytes as a scenario file: loaded and checked (faults too), or one line."""
    path = scratch() / "fuzz.toml"
    path.write_bytes(data)
    try:
        sc = scenario.load_scenario(path)
        Faults(sc.faults, sc.scenario.seed)
    except UserError as exc:
        if "\n" in str(exc):
            raise Broken(f"UserError over several lines: {exc!r}") from None


def scenario_seeds() -> list[bytes]:
    return [p.read_bytes() for p in sorted((ROOT / "scenarios").glob("*.toml"))]


def scenario_dictionary() -> list[bytes]:
    """Section and key names, so mutations make documents the checker reads past."""
    words = {f"[{s}]" for s in scenario.SCHEMA}
    words |= {k for keys in scenario.SCHEMA.values() for k in keys}
    return sorted(w.encode() for w in words) + [b" = ", b"true", b"inf", b"nan", b"[[", b"]]"]


class Target:
    """One coverage-guided target: what it runs, the modules whose edges guide it (a name
    and every module under it), its seeds, its longest input (0: the longest seed's
    length) and the words libFuzzer may splice in."""

    def __init__(self, label: str, unit: str, one_input: Callable[[bytes], None],
                 code: tuple[str, ...], seeds: Callable[[], list[bytes]], max_len: int = 512,
                 dictionary: Callable[[], list[bytes]] | None = None) -> None:
        self.label, self.unit, self.one_input, self.seeds = label, unit, one_input, seeds
        self.code, self.max_len, self.dictionary = code, max_len, dictionary


# --- Protocol 2.0: the parser and the bus of 18 XL430s ----------------------------------------
def parser2_one_input(data: bytes) -> None:
    """The bytes as garbage, then after a gap one valid (stuffed) packet the Protocol 2.0
    parser must find again; every packet it reports took bytes on the line, CRC right."""
    want = dx2.packet(len(data) % 0xFD, data[0] if data else dx2.PING, data[-5:])
    _resync(dx2.Parser(), data, want, dx2.MAX_PACKET, _reported2)


def _reported2(p: dx2.Parser, stream: bytes, i: int) -> bytes:
    """The bytes the packet took on the line (it ends before those the parser still holds):
    a header and a right CRC."""
    wire = stream[i + 1 - p.pending() - p.raw_len:i + 1 - p.pending()]
    if wire[:4] != b"\xff\xff\xfd\x00" or \
            dx2.crc16(wire, 0, len(wire) - 2) != wire[-2] | wire[-1] << 8:
        raise Broken(f"parser reported a packet with a bad CRC {wire.hex()}")
    return wire


def parser2_seeds() -> list[bytes]:
    return [b"", dx2.ping(1), dx2.write(1, 0, b"\xff\xff\xfd\xff"),
            dx2.sync_read(132, 4, [1, 2], fast=True), dx2.fast_status([(0, 1, b"\xff\xff")]),
            b"\xff\xff\xfd\x00\x01\xff\x03"]


def bus2_one_input(data: bytes) -> None:
    """A fresh bus of 18 XL430s, then the bytes as instructions (byte 0 of each: how many
    of the next bytes are its parameters) or raw; after them every register within its
    range and a PING answered once the line idled."""
    spec = fuzz_v2_bus.XL430
    bus = spec.fresh_bus()
    i = 0
    while i + 2 < len(data):
        n = data[i] & 15
        pkt = dx2.packet(data[i + 1] % 0xFD if data[i] & 16 else 1 + data[i + 1] % 18,
                         data[i + 2], data[i + 3:i + 3 + n])
        bus.master_write(pkt if data[i] & 32 == 0 else pkt[:len(pkt) // 2])
        bus.master_read(spec.read_bytes, READS_US[data[i] >> 6 if data[i] >> 6 < 3 else 0])
        i += 3 + n
    _after_stream(spec, bus)


def bus2_seeds() -> list[bytes]:
    return [bytes((0, 1, dx2.PING)), bytes((4, 2, dx2.READ, 132, 0, 4, 0)),
            bytes((5, 3, dx2.WRITE, 64, 0, 1, 0, 0)),
            bytes((7, 0xFE, dx2.SYNC_READ, 132, 0, 4, 0, 1, 2, 3))]


# --- the STM32F411 ELF loader ---------------------------------------------------------------
def elf_one_input(data: bytes) -> None:
    """The bytes as an ELF given to --firmware: loaded, or one line."""
    path = scratch() / "fuzz.elf"
    path.write_bytes(data)
    try:
        load_elf(path).function_at(0x08000000)
    except UserError as exc:
        if "\n" in str(exc):
            raise Broken(f"UserError over several lines: {exc!r}") from None


def elf_seeds() -> list[bytes]:
    whole = fuzz_elf.sample_elf()
    return [whole, whole[:len(whole) // 2]]


# --- a robot's logs imported ------------------------------------------------------------------
LOG_SUFFIXES = (".sr", ".asc", ".blf", ".log")


def logs_one_input(data: bytes) -> None:
    """Byte 0 picks the kind (a sigrok capture or one of three CAN logs), the rest is the
    file: imported (a capture also checked), or refused in one line."""
    if not data:
        return
    src = scratch() / f"mutant{LOG_SUFFIXES[data[0] % len(LOG_SUFFIXES)]}"
    src.write_bytes(data[1:])
    escaped = fuzz_logs.one_log(src, scratch() / "imported.mcap")
    if escaped:
        raise Broken(escaped)


def logs_seeds() -> list[bytes]:
    """A capture of a few READs and replies, and a CAN log by each of python-can's writers."""
    sr = fuzz_logs.sr_file(fuzz_logs.METADATA, fuzz_logs.line_samples())
    logs = fuzz_logs.can_logs(scratch())
    return [bytes([0]) + sr] + [bytes([LOG_SUFFIXES.index(k)]) + v for k, v in logs.items()]


_DXL, _SERVOS = "hexhil.protocol.dynamixel", "hexhil.hil.servobus"
TARGETS = {
    "parser": Target("protocol parser (atheris)", "streams", parser_one_input, (f"{_DXL}.v1",),
                     parser_seeds, dxl.MAX_PACKET + 41),
    "can": Target("CAN frame codecs (atheris)", "frames", can_one_input,
                  ("hexhil.protocol.can_frames",), can_seeds),
    "bus": Target("emulated bus, 18 servos (atheris)", "streams", bus_one_input, (_SERVOS, _DXL),
                  bus_seeds),
    "scenario": Target("TOML scenario loader (atheris)", "documents", scenario_one_input,
                       ("hexhil.hil.scenario", "hexhil.protocol", f"{_SERVOS}.faults",
                        "tomllib"), scenario_seeds, 4096, scenario_dictionary),
    "trace": Target("MCAP reader + recover (atheris)", "files", trace_one_input,
                    ("hexhil.trace", "mcap"), trace_seeds, 0),
    "parser2": Target("protocol 2.0 parser (atheris)", "streams", parser2_one_input,
                      (f"{_DXL}.v2",), parser2_seeds, 600),
    "bus2": Target("protocol 2.0 bus, 18 XL430s (atheris)", "streams", bus2_one_input,
                   (_SERVOS, _DXL), bus2_seeds),
    "elf": Target("STM32F411 ELF loader (atheris)", "files", elf_one_input, ("hexhil.hil.mcu",),
                  elf_seeds, 0),
    "logs": Target("robot log import (atheris)", "files", logs_one_input,
                   ("hexhil.trace", "hexhil.dynamixel", "mcap"), logs_seeds, 0),
}
