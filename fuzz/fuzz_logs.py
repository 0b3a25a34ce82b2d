"""A robot's logs imported (host_tools/trace/import_logs.py) from mutated files: sigrok
captures of the servo line (the zip cut or flipped, or a whole zip around mutated samples
and metadata), and CAN logs by python-can's ASC, BLF and candump writers. Every mutant is
imported, or refused in one line (UserError); a capture that imports is also checked
(``check_capture``)."""
from __future__ import annotations

import random
import tempfile
import zipfile
from pathlib import Path

import can

from fuzz.fuzz_trace import mutate
from fuzz.tally import Budget, Tally
from hexhil.dynamixel.conformance.capture import check_capture
from hexhil.trace.import_logs import import_log
from hexhil.protocol.dynamixel import v1 as dxl
from hexhil.protocol.errors import UserError

RATE_HZ = 4_000_000
BAUD = 1_000_000
METADATA = ("[global]\nsigrok version=0.5.2\n\n[device 1]\ncapturefile=logic-1\n"
            "total probes=3\nsamplerate=4 MHz\ntotal analog=0\nprobe1=0\nprobe2=1\nprobe3=2\n"
            "unitsize=1\n")


def line_samples() -> bytes:
    """A few READs and their statuses on one line, bit 2 the direction: samples at 4 MHz."""
    spb = RATE_HZ // BAUD
    out = bytearray([0b001] * 40)
    for k in range(6):
        for who, packet in ((1, dxl.read(1 + k, 36, 2)), (0, dxl.status(1 + k, 0, b"\x00\x02"))):
            for byte in packet:
                for bit in [0] + [(byte >> i) & 1 for i in range(8)] + [1]:
                    out += bytes([bit | (who << 2)]) * spb
            out += bytes([0b001]) * (20 * spb)
    return bytes(out)


def sr_file(metadata: str, samples: bytes) -> bytes:
    """A sigrok session zip holding ``metadata`` and one chunk of ``samples``."""
    path = Path(tempfile.mkstemp(suffix=".sr")[1])
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("version", "2")
        z.writestr("metadata", metadata)
        z.writestr("logic-1-1", samples)
    data = path.read_bytes()
    path.unlink()
    return data


def can_logs(folder: Path) -> dict[str, bytes]:
    """A CAN log by each of python-can's ASC, BLF and candump -L writers."""
    msgs = [can.Message(timestamp=1e9 + 0.01 * i, arbitration_id=0x100 + i % 3,
                        data=bytes([i] * (i % 9)), is_extended_id=False, is_rx=i % 2 == 0)
            for i in range(30)]
    out = {}
    for suffix, writer in ((".asc", can.ASCWriter), (".blf", can.BLFWriter),
                           (".log", can.CanutilsLogWriter)):
        path = folder / f"seed{suffix}"
        w = writer(str(path))
        for m in msgs:
            w.on_message_received(m)
        w.stop()
        out[suffix] = path.read_bytes()
    return out


def one_log(src: Path, dst: Path) -> str | None:
    """Import ``src`` (and check it, a capture): None, or what escaped."""
    steps = [("import", lambda: import_log(src, dst, overwrite=True))]
    if src.suffix == ".sr":
        steps.append(("check", lambda: check_capture(src)))
    for step, fn in steps:
        try:
            fn()
        except UserError as exc:
            if "\n" in str(exc):
                return f"{step}: UserError over several lines: {exc!r}"
            return None
        except Exception as exc:  # an escape is what the fuzzer is for
            return f"{step}: {exc.__class__.__name__}: {exc}"
    return None


def run(seed: int, budget_s: float | None, limit: int | None) -> list[Tally]:
    rng = random.Random(seed)
    tally = Tally("robot log import (sr, asc, blf, log)", "files")
    budget = Budget(budget_s, limit)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        samples = line_samples()
        seeds = {".sr": sr_file(METADATA, samples), **can_logs(folder)}
        dst = folder / "out.mcap"
        while budget.more(tally.inputs):
            tally.inputs += 1
            suffix = rng.choice(sorted(seeds) + [".sr-inside"])
            if suffix == ".sr-inside":   # a whole zip, its samples or metadata mutated
                meta, raw = METADATA, samples
                if rng.random() < 0.5:
                    meta = mutate(rng, METADATA.encode()).decode("latin-1")
                else:
                    raw = mutate(rng, samples)
                data, suffix = sr_file(meta, raw), ".sr"
            else:
                data = mutate(rng, seeds[suffix])
            src = folder / f"mutant{suffix}"
            src.write_bytes(data)
            escaped = one_log(src, dst)
            if escaped:
                tally.escape(f"file {tally.inputs} ({suffix}) {escaped}")
    tally.wall_s = budget.elapsed_s()
    return [tally]
