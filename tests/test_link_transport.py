"""Where the firmware connects (hil/link/firmware_child.py ``_listen``): our firmware
on a Unix socket in a directory of its own, gone once it has connected; a command of the
caller's on the documented 127.0.0.1 TCP port. Both carry the same run."""
from __future__ import annotations

import os
import socket

import pytest

from hexhil.hil.link.firmware_child import FirmwareProcess
from hexhil.hil.link.firmware_process import firmware_command
from hexhil.hil.run.lockstep import Simulator
from hexhil.hil.scenario import load_scenario
from hexhil.protocol import sim_link


def _hello(fw: FirmwareProcess) -> None:
    msgs, closed = fw.conn.batch()
    assert not closed and msgs[-1][0] == sim_link.OP_HELLO   # the link carries the hello


@pytest.mark.parametrize("python", ["micropython", "cpython"])
def test_our_firmware_connects_on_a_unix_socket(python: str) -> None:
    fw = FirmwareProcess(python)
    try:
        sock = fw.conn.sock
        assert sock.family == socket.AF_UNIX
        _hello(fw)
        path = sock.getsockname()   # the listener's: nothing of it is left behind
        assert path.endswith("/link") and not os.path.exists(os.path.dirname(path))
    finally:
        fw.kill()


def test_a_command_of_the_callers_gets_the_tcp_port() -> None:
    fw = FirmwareProcess("micropython", command=firmware_command("micropython"))
    try:
        assert fw.conn.sock.family == socket.AF_INET
        assert fw.conn.sock.getsockname()[0] == "127.0.0.1"
        _hello(fw)
    finally:
        fw.kill()


def test_both_carry_the_same_run() -> None:
    sc = load_scenario("scenarios/flat-tripod.toml")
    unix = Simulator(sc, seed=2).run(2.0, python="micropython")
    tcp = Simulator(sc, seed=2).run(2.0, python="micropython",
                                    command=firmware_command("micropython"))
    assert unix.cycles == tcp.cycles > 90
    assert unix.serial_digest == tcp.serial_digest


def test_no_unix_socket_where_the_temporary_path_is_too_long(tmp_path, monkeypatch) -> None:
    """A socket's path holds at most 107 bytes: past that our firmware takes the port."""
    deep = tmp_path / ("d" * 120)
    deep.mkdir()
    monkeypatch.setenv("TMPDIR", str(deep))
    monkeypatch.setattr("tempfile.tempdir", None)   # read TMPDIR again
    fw = FirmwareProcess("micropython")
    try:
        assert fw.conn.sock.family == socket.AF_INET
        _hello(fw)
    finally:
        fw.kill()
    assert list(deep.iterdir()) == []   # the directory made for the socket is gone
