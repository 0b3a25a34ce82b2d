"""`hexhil run --can-server`: a stock python-can socketcand client sees every frame of a run."""
from __future__ import annotations

import subprocess
import sys
import threading

import can

from hexhil.trace import protobuf as pb
from hexhil.trace import topics
from hexhil.trace.reader import open_trace


def test_stock_client_receives_every_frame_of_hexhil_run(tmp_path):
    trace = tmp_path / "live.mcap"
    proc = subprocess.Popen(
        [sys.executable, "-m", "hexhil.cli", "run", "scenarios/faults.toml", "--duration", "2",
         "--out", str(trace), "--can-server", "0", "--can-wait", "1"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    line = proc.stdout.readline()
    assert line.startswith("can-server: 127.0.0.1:"), line
    _, host_port, _, channel = line.split()[:4]  # "can-server: HOST:PORT channel CH ..."
    port = int(host_port.rsplit(":", 1)[1])
    client = can.Bus(interface="socketcand", channel=channel, host="127.0.0.1", port=port)
    received: list[can.Message] = []
    done = threading.Event()

    def listen() -> None:
        while True:
            m = client.recv(timeout=0.5)
            if m is not None:
                received.append(m)
            elif done.is_set():
                return

    t = threading.Thread(target=listen)
    t.start()
    try:
        out, err = proc.communicate(timeout=120)
    finally:
        done.set()
        t.join(timeout=10)
        client.shutdown()
    assert proc.returncode == 0, err
    with open_trace(trace) as tr:
        sent = [(m.log_time_ns, pb.CanFrame.FromString(m.data)) for m in tr.messages([topics.T_CAN_RAW])]
    want = [(f.arbitration_id, f.data) for _, f in sent if f.direction == "tx"]
    assert len(want) >= 20
    assert [(m.arbitration_id, bytes(m.data)) for m in received] == want


def test_can_server_port_in_use_is_one_line(tmp_path):
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        port = s.getsockname()[1]
        p = subprocess.run([sys.executable, "-m", "hexhil.cli", "run", "scenarios/faults.toml",
                            "--duration", "1", "--can-server", str(port)],
                           capture_output=True, text=True, timeout=60)
    assert p.returncode == 2
    assert p.stderr.count("\n") == 1 and "cannot listen" in p.stderr and "Traceback" not in p.stderr
