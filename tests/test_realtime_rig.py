"""`hexhil bus --world`: the MuJoCo world in real time for any firmware (a few seconds
each; pacing is reported, never asserted, since the machine is shared)."""
from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

from ctrl_c import sigint_default
from hexhil.trace.reader import Trace
from hexhil.trace.topics import T_BODY, T_SERIAL
from hexhil.protocol.dynamixel import v1 as dxl
from conftest import HEXHIL, ROOT

MICROPYTHON = Path(sys.executable).with_name("micropython")


def _rig(*flags: str) -> tuple[subprocess.Popen, str]:
    proc = subprocess.Popen([*HEXHIL, "bus", "--world", "scenarios/flat-tripod.toml", "--json",
                             *flags], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, preexec_fn=sigint_default)
    line = proc.stdout.readline().strip()
    assert line.startswith(("pty: ", "tcp: ")), (line, proc.stderr.read() if proc.poll() else "")
    return proc, line.split(": ", 1)[1]


def _summary(proc: subprocess.Popen, stop: bool = False) -> dict:
    if stop:
        proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0 and "Traceback" not in err, err
    return json.loads(out.strip().splitlines()[-1])


def test_our_firmware_walks_on_its_real_code_path(tmp_path: Path):
    trace = tmp_path / "rt.mcap"
    proc, pty = _rig("--duration", "6", "--out", str(trace))
    env = dict(os.environ, MICROPYPATH=f"{ROOT}:.frozen")
    fw = subprocess.run([str(MICROPYTHON), "firmware/main.py", "--serial", pty], cwd=ROOT,
                        env=env, capture_output=True, text=True, timeout=60)
    s = _summary(proc)
    stats = json.loads([ln for ln in fw.stdout.splitlines() if ln.startswith("event 3 ")][-1][8:])
    assert stats["found"] == 18 and stats["state"] == "walking", fw.stdout[-2000:]
    assert s["sensor_node"]["instructions"] > 50          # switches read every cycle
    assert s["bus"]["packets"] > 200 and s["body"]["dx_m"] > 0.0
    assert set(s["pacing"]) >= {"max_lag_ms", "p99_lag_ms", "late_steps"}
    tr = Trace(trace)                                     # finished, readable by the reader
    topics = {m.topic for m in tr.messages()}
    assert {T_SERIAL, T_BODY, "/joints", "/servos"} <= topics


def test_sdk_tripod_drives_the_rig():
    proc, pty = _rig("--duration", "5")
    sdk = subprocess.run([sys.executable, "examples/sdk_tripod.py", pty, "--seconds", "3"],
                         cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert sdk.returncode == 0 and "sensor node: model 0x5348" in sdk.stdout, sdk.stderr
    s = _summary(proc)
    assert s["bus"]["packets"] > 50 and s["sensor_node"]["instructions"] > 10


def test_garbage_and_reconnects_never_kill_the_rig():
    proc, addr = _rig("--tcp", "0")
    host, port = addr.rsplit(":", 1)
    for _ in range(2):                                    # disconnect, reconnect, garbage
        with socket.create_connection((host, int(port))) as c:
            c.sendall(b"\x00garbage\x07" + dxl.ping(2)[:-1] + b"\x00")
    with socket.create_connection((host, int(port)), timeout=20) as c:
        c.sendall(dxl.ping(1))
        got = b""
        deadline = time.monotonic() + 20
        while dxl.status(1) not in got and time.monotonic() < deadline:
            got += c.recv(64)                         # after the checksum-error statuses
        assert dxl.status(1) in got
    s = _summary(proc, stop=True)
    assert s["bus"]["replies"] >= 1 and s["violations"]["counts"]["bad_checksum"] >= 1
