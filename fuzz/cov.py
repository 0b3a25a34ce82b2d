"""The coverage-guided phase of ``make fuzz``: each target of ``fuzz/cov_targets.py`` under
atheris (libFuzzer) in a subprocess, for a set number of runs and a set seed.

libFuzzer ends its process on a crash (and atexit hooks do not run when it is done), so
the figures come from what it prints: ``stat::number_of_executed_units`` and the last
``cov:``/``ft:`` line (edges and features reached). A crash leaves its input in the run's
folder; it is minimised here, by replaying it without atheris, and reported in hex.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Callable

from fuzz.cov_targets import TARGETS
from fuzz.tally import Tally

ROOT = Path(__file__).resolve().parent.parent
FINDINGS = ROOT / "out" / "fuzz"
MINIMISE_TRIES = 3_000
PER_INPUT_TIMEOUT_S = 30  # a hang is a crash too


def _crash(one_input: Callable[[bytes], None], data: bytes) -> str:
    """What ``data`` raises, as 'ExcType: message', or '' when it runs clean."""
    try:
        one_input(data)
    except Exception as exc:  # replaying a crash: whatever it raises is the finding
        return f"{exc.__class__.__name__}: {str(exc)[:300]}"
    return ""


def minimise(one_input: Callable[[bytes], None], data: bytes) -> tuple[bytes, str]:
    """The shortest input found by cutting spans out (halves, quarters, ... single bytes)
    that still raises the same exception type; and what it raises."""
    what = _crash(one_input, data)
    kind = what.split(":", 1)[0]
    tries = 0
    span = max(1, len(data) // 2)
    while what and span >= 1 and tries < MINIMISE_TRIES:
        at = 0
        while at < len(data) and tries < MINIMISE_TRIES:
            tries += 1
            cut = data[:at] + data[at + span:]
            got = _crash(one_input, cut)
            if got.split(":", 1)[0] == kind:
                data, what = cut, got
            else:
                at += span
        span //= 2
    return data, what


def _write_inputs(folder: Path, inputs: list[bytes]) -> None:
    folder.mkdir()
    for i, data in enumerate(inputs):
        (folder / f"seed-{i:03d}").write_bytes(data)


def _dictionary(path: Path, words: list[bytes]) -> None:
    path.write_text("".join('"' + "".join(f"\\x{b:02x}" for b in w) + '"\n' for w in words))


def _last(pattern: str, text: str) -> int:
    found = re.findall(pattern, text)
    return int(found[-1]) if found else 0


def run(name: str, seed: int, runs: int) -> Tally:
    """``runs`` inputs of target ``name`` from its seed corpus, libFuzzer seeded with
    ``seed`` (>= 1: 0 would make libFuzzer pick one)."""
    target = TARGETS[name]
    tally = Tally(target.label, target.unit)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="hexhil-fuzz-") as tmp:
        work = Path(tmp)
        seeds = target.seeds()
        _write_inputs(work / "seeds", seeds)
        (work / "corpus").mkdir()  # libFuzzer adds what it finds to the first folder
        flags = [f"-runs={runs}", f"-seed={max(1, seed)}", f"-artifact_prefix={work}/",
                 f"-timeout={PER_INPUT_TIMEOUT_S}", "-print_final_stats=1",
                 f"-max_len={target.max_len or max(map(len, seeds))}"]
        if target.dictionary is not None:
            _dictionary(work / "words.dict", target.dictionary())
            flags.append(f"-dict={work / 'words.dict'}")
        env = dict(os.environ, TMPDIR=tmp, PYTHONPATH=str(ROOT))
        proc = subprocess.run([sys.executable, "-m", "fuzz.cov_harness", name, *flags,
                               str(work / "corpus"), str(work / "seeds")], cwd=ROOT, env=env,
                              capture_output=True, text=True, errors="replace")
        out = proc.stderr + proc.stdout
        tally.inputs = _last(r"stat::number_of_executed_units:\s*(\d+)", out)
        tally.notes["cov"] = _last(r"\bcov: (\d+)", out)
        tally.notes["ft"] = _last(r"\bft: (\d+)", out)
        tally.notes["corpus"] = _last(r"\bcorp: (\d+)/", out)
        if name == "parser":  # every parser input checks the resync; a miss is a crash
            tally.resync_checked = tally.inputs
        found = sorted(p for p in work.iterdir() if p.name.split("-")[0] in
                       ("crash", "timeout", "oom", "leak"))
        if proc.returncode or found:
            tally.escape(_finding(name, proc.returncode, found, out))
        elif name == "parser":
            tally.resync_found = tally.inputs
    tally.wall_s = time.perf_counter() - t0
    return tally


def _finding(name: str, returncode: int, found: list[Path], out: str) -> str:
    """One line for the table: the minimal input in hex (whole, and kept in
    ``out/fuzz/<target>-<kind>.bin`` for a regression test) and what it raises."""
    if not found:
        tail = " | ".join(out.strip().splitlines()[-3:])
        return f"{name}: libFuzzer exited {returncode} with no input saved: {tail}"
    data = found[0].read_bytes()
    kind = found[0].name.split("-")[0]
    what = f"a {kind} (over {PER_INPUT_TIMEOUT_S} s)" if kind == "timeout" else kind
    if kind == "crash":
        data, what = minimise(TARGETS[name].one_input, data)
        what = what or "no crash when replayed without atheris"
    FINDINGS.mkdir(parents=True, exist_ok=True)
    kept = FINDINGS / f"{name}-{kind}.bin"
    kept.write_bytes(data)
    return f"{name}: minimal input ({len(data)} bytes, {kept}) {data.hex() or '(empty)'} -> {what}"
