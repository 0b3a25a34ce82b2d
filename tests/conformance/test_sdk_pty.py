"""The SDK's real PortHandler over a pseudo-terminal: its bytes on the wire equal ours, and
it reads the status packets we write back (the path an emulated bus takes)."""
from __future__ import annotations

import os
import pty
import select
import threading
import tty

import dynamixel_sdk as sdk
import pytest

from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl


class PtyServo:
    """One emulated AX-12 on the master side of a pty, answering from a control table."""

    def __init__(self, dev_id: int) -> None:
        self.master, slave = pty.openpty()
        tty.setraw(slave)
        self.path = os.ttyname(slave)
        self._slave = slave
        self.dev_id = dev_id
        self.table = ax12.defaults()
        self.heard = bytearray()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        parser = dxl.Parser()
        while not self._stop.is_set():
            ready, _, _ = select.select([self.master], [], [], 0.05)
            if not ready:
                continue
            data = os.read(self.master, 512)
            self.heard += data
            for pkt in parser.feed(data):
                if pkt.id != self.dev_id:
                    continue
                if pkt.code == dxl.READ:
                    a, n = pkt.params
                    os.write(self.master, dxl.status(self.dev_id, 0, bytes(self.table[a:a + n])))
                elif pkt.code == dxl.WRITE:
                    a = pkt.params[0]
                    self.table[a:a + len(pkt.params) - 1] = pkt.params[1:]
                    os.write(self.master, dxl.status(self.dev_id))
                else:
                    os.write(self.master, dxl.status(self.dev_id))

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2)
        os.close(self.master)
        os.close(self._slave)


@pytest.fixture()
def servo(monkeypatch: pytest.MonkeyPatch):
    # The SDK's reply timeout is 2 x LATENCY_TIMER ms + 2 ms; a roomy one keeps a loaded
    # machine from failing the test (a prompt reply costs no time either way).
    monkeypatch.setattr(sdk.port_handler, "LATENCY_TIMER", 100)
    s = PtyServo(5)
    yield s
    s.close()


def test_sdk_over_pty(servo: PtyServo) -> None:
    port = sdk.PortHandler(servo.path)
    assert port.openPort() and port.setBaudRate(1000000)
    ph = sdk.PacketHandler(1.0)
    try:
        assert ph.ping(port, 5) == (ax12.MODEL_NUMBER, sdk.COMM_SUCCESS, 0)
        assert ph.write2ByteTxRx(port, 5, ax12.GOAL_POSITION, 700) == (sdk.COMM_SUCCESS, 0)
        assert ph.read2ByteTxRx(port, 5, ax12.GOAL_POSITION) == (700, sdk.COMM_SUCCESS, 0)
        assert ph.read1ByteTxRx(port, 5, ax12.TEMPERATURE_LIMIT) == (70, sdk.COMM_SUCCESS, 0)
    finally:
        port.closePort()
    assert bytes(servo.heard) == (dxl.ping(5) + dxl.read(5, 0, 2)
                                  + dxl.write(5, ax12.GOAL_POSITION, (700).to_bytes(2, "little"))
                                  + dxl.read(5, ax12.GOAL_POSITION, 2)
                                  + dxl.read(5, ax12.TEMPERATURE_LIMIT, 1))
