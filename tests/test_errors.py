"""The errors a user can act on: one base, ``UserError``, whose kinds are also the built-in
error a Python caller already catches; exit statuses are the command line's alone."""
from __future__ import annotations

import socket
from pathlib import Path
from types import SimpleNamespace

import pytest

import hexhil as hx
from hexhil import cli, executor, run_summary
from hexhil.hil.mcu import gdb
from hexhil.protocol.errors import BadFile, BadValue, TimedOut, UserError
from conftest import ROOT


def test_a_value_outside_its_rules_is_a_value_error() -> None:
    with pytest.raises(ValueError, match="duration_s must be positive") as got:
        hx.Run(ROOT / "scenarios" / "flat-tripod.toml", duration_s=-1)
    assert isinstance(got.value, BadValue) and isinstance(got.value, UserError)


def test_an_unwritable_trace_is_an_os_error(tmp_path: Path) -> None:
    with pytest.raises(OSError, match="is a directory") as got:
        hx.Run(ROOT / "scenarios" / "flat-tripod.toml", duration_s=0.1, trace=tmp_path)
    assert isinstance(got.value, BadFile) and isinstance(got.value, UserError)
    assert str(got.value).endswith("is a directory, not a trace file")


def test_the_base_alone_is_neither() -> None:
    err = UserError("another run is writing this trace now")
    assert not isinstance(err, (ValueError, OSError))


def test_clients_that_do_not_come_in_time_are_a_timeout_error(monkeypatch, capsys) -> None:
    monkeypatch.setattr(run_summary, "CAN_WAIT_TIMEOUT_S", 0.2)
    scenario = str(ROOT / "scenarios" / "flat-tripod.toml")
    with pytest.raises(TimeoutError, match="1 socketcand client.s. did not attach") as got:
        run_summary.run(scenario, duration_s=0.1, can_server_port=0, can_wait_clients=1)
    assert isinstance(got.value, TimedOut) and isinstance(got.value, UserError)
    monkeypatch.setattr(gdb, "ACCEPT_S", 0.1)
    with pytest.raises(TimeoutError, match=r"gdb_port 0: no GDB client came in 0.1 s") as got:
        gdb.GdbServer(SimpleNamespace(core=None), 0)
    assert isinstance(got.value, TimedOut) and got.value.params == ("gdb_port",)
    assert cli.main(["run", scenario, "--can-server", "0", "--can-wait", "1"]) == 2
    assert capsys.readouterr().err == ("hexhil: --can-wait: 1 socketcand client(s) did not "
                                       "attach within 0 s\n")


def test_a_port_taken_or_refused_is_an_os_error() -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        with pytest.raises(OSError, match=f"cannot listen on 127.0.0.1:{port}") as got:
            gdb.GdbServer(SimpleNamespace(core=None), port)
        assert isinstance(got.value, BadFile)
    with pytest.raises(OSError, match=f"cannot reach Dask scheduler tcp://127.0.0.1:{port}"):
        executor.dask_client(f"tcp://127.0.0.1:{port}")     # closed now: refused at once
    with pytest.raises(ValueError, match="the port is not a number"):
        executor.dask_client("tcp://127.0.0.1:abc")


def test_the_command_line_maps_every_kind_to_exit_2(tmp_path: Path, capsys) -> None:
    scenario = str(ROOT / "scenarios" / "flat-tripod.toml")
    assert cli.main(["run", scenario, "--duration", "-1"]) == cli.EXIT_BAD_INPUT == 2
    assert cli.main(["run", scenario, "--duration", "0.1", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith("hexhil: --duration must be positive")
    assert err[-1].endswith("is a directory, not a trace file") and len(err) == 2
