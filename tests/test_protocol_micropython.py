"""The protocol tests under the real ``micropython`` binary (tests/micropython/mpy_*.py).

Each script is plain asserts and ends with ``OK <module> <checks>``. Scripts run under
CPython too, and both interpreters must print the same lines before it (the check counts
may differ: the allocation checks run only under MicroPython).
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import cantools
import pytest

from mpy import ROOT, run_micropython
from hexhil.protocol import can_frames as cf

SCRIPTS = sorted((ROOT / "tests" / "micropython").glob("mpy_*.py"))


def _cpython(script: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, str(script)], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.stem)
def test_script_passes_under_micropython_and_cpython(script: Path) -> None:
    mpy = run_micropython(script)
    assert mpy.returncode == 0, mpy.stderr + mpy.stdout
    last = mpy.stdout.strip().splitlines()[-1].split()
    assert last[0] == "OK" and last[1] == script.stem[4:] and int(last[2]) > 0, mpy.stdout
    cpy = _cpython(script)
    assert cpy.returncode == 0, cpy.stderr
    assert cpy.stdout.splitlines()[:-1] == mpy.stdout.splitlines()[:-1]
    assert cpy.stdout.splitlines()[-1].startswith("OK " + script.stem[4:] + " ")


def test_scripts_cover_every_protocol_module() -> None:
    modules = {p.stem for p in (ROOT / "protocol").glob("*.py")} - {"__init__"}
    assert modules <= {s.stem[4:] for s in SCRIPTS}


def test_micropython_can_bytes_agree_with_cantools() -> None:
    db = cantools.database.load_file(str(ROOT / "protocol" / "hexhil.dbc"))
    out = run_micropython(ROOT / "tests" / "micropython" / "mpy_can_frames.py")
    frames = [line.split() for line in out.stdout.splitlines() if line.startswith("frame ")]
    assert len(frames) >= len(cf.FRAMES)
    for _, name, arb_hex, data_hex in frames:
        data = bytes.fromhex(data_hex)
        assert int(arb_hex, 16) == db.get_message_by_name(name).frame_id
        assert db.decode_message(name, data, decode_choices=False) == cf.decode(int(arb_hex, 16), data)[1]
        assert db.encode_message(name, cf.decode(int(arb_hex, 16), data)[1]) == data
