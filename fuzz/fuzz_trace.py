"""The MCAP reader and recover path (host_tools/trace/reader.py, recover.py) on mutated
traces: every mutant gives a one-line UserError or reads, and ``recover`` gives a
one-line UserError or a finished file that reads back whole."""
from __future__ import annotations

import random
import tempfile
from pathlib import Path

from fuzz.tally import Budget, Tally
from hexhil.trace import reader, recover
from hexhil.trace.recorder import Recorder
from hexhil.protocol import can_frames as cf
from hexhil.protocol.dynamixel import v1 as dxl
from hexhil.protocol.errors import UserError

SECONDS = 3  # six 0.5 s chunks


def sample_trace(path: Path, seconds: int = SECONDS) -> bytes:
    """A small trace with every kind of record the recorder writes."""
    with Recorder(path, {"scenario": "fuzz", "seed": 0}) as rec:
        for k in range(seconds * 100):
            t = k * 10_000
            rec.serial(t, "tx", dxl.read(1 + k % 18, 36, 2))
            rec.serial(t + 700, "rx", dxl.status(1 + k % 18, 0, bytes((k & 0xFF, 2))))
            rec.can(t, *cf.encode("heartbeat", state=2, fault_flags=0, cycle=k, overruns=0))
            rec.telemetry(t, {"cycle": k, "state": "walking"})
            rec.body_pose(t, (0.001 * k, 0.0, 0.1), (1.0, 0.0, 0.0, 0.0))
            if k % 50 == 0:
                rec.fault(t, "bit_error", f"byte {k}")
            rec.advance(t)
    return path.read_bytes()


def mutate(rng: random.Random, data: bytes) -> bytes:
    """Cut, flip, splice, zero or duplicate a span: what crashes and bad disks leave."""
    kind = rng.randrange(5)
    n = len(data)
    at = rng.randrange(n)
    if kind == 0:
        return data[:at]
    out = bytearray(data)
    if kind == 1:
        for _ in range(rng.randrange(1, 8)):
            out[rng.randrange(n)] ^= 1 << rng.randrange(8)
        return bytes(out)
    span = rng.randrange(1, 400)
    if kind == 2:
        out[at:at + span] = bytes(min(span, n - at))
        return bytes(out)
    if kind == 3:
        return data[:at] + data[at + span:]
    return data[:at] + data[rng.randrange(n):][:span] + data[at:]


def _read_all(path: Path) -> int:
    with reader.Trace(path) as trace:
        trace.metadata()
        return sum(1 for _ in trace.decoded())


def run(seed: int, budget_s: float | None, limit: int | None) -> list[Tally]:
    rng = random.Random(seed)
    tally = Tally("MCAP reader + recover", "files")
    budget = Budget(budget_s, limit)
    with tempfile.TemporaryDirectory() as tmp:
        base = sample_trace(Path(tmp) / "base.mcap")
        src, dst = Path(tmp) / "mutant.mcap", Path(tmp) / "recovered.mcap"
        while budget.more(tally.inputs):
            tally.inputs += 1
            src.write_bytes(mutate(rng, base))
            for step, fn in (("read", lambda: _read_all(src)),
                             ("info", lambda: reader.info(src)),
                             ("recover", lambda: recover.recover(src, dst, overwrite=True)),
                             ("read recovered", lambda: _read_all(dst))):
                try:
                    fn()
                except UserError as exc:
                    if "\n" in str(exc):
                        tally.escape(f"{step}: UserError over several lines: {exc!r}")
                    if step == "recover":
                        break
                    tally.notes[f"{step} refused"] = tally.notes.get(f"{step} refused", 0) + 1
                except Exception as exc:  # an escape is what the fuzzer is for
                    tally.escape(f"file {tally.inputs} {step}: {exc.__class__.__name__}: {exc}")
                    break
    tally.wall_s = budget.elapsed_s()
    return [tally]
