"""A real-time run for a master that is not ours (``hexhil bus``, ``hexhil bus --world``): the
scenario's emulated servos, and with ``world`` its robot, paced to the wall clock behind a
serial line: a real board behind a USB adapter (``SerialPort``), a client on a pty
(``Pty``, e.g. the stock dynamixel-sdk) or a TCP socket (``Tcp``).

It is ``Run``'s counterpart (host_tools/lockstep_run.py): the same run core (hil/run/realtime_rig.py
on hil/run/core.py) and a trace with the same metadata, the scenario's data included, so
``hexhil test --trace`` and ``scenario_of_trace`` read it like a lockstep run's. The trace's
``command`` is ``bus`` (nothing spoke the firmware link).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Sequence, Union

from hil import scenario as scenario_mod
from hil.servobus import serial_server
from hil.run.realtime_rig import RealTimeRig
from hil.scenario import DEFAULT_BAUD, Scenario
from hil.seams import CanGateway
from hil.servobus.switch_node import DEFAULT_ID
from host_tools.lockstep_run import trace_metadata
from protocol.dynamixel import models
from protocol.errors import UserError

EXTERNAL = "external"        # a run's firmware_runtime: the master on the line is not ours
WORLD_STEP_US = 2_000        # the world catches up in steps this long


@dataclass(frozen=True)
class Pty:
    """A pseudo-terminal (its path is announced)."""


@dataclass(frozen=True)
class Tcp:
    port: int
    host: str = "127.0.0.1"


@dataclass(frozen=True)
class Rfc2217:
    """pyserial's RFC 2217 server (clients open ``rfc2217://host:port``); with
    ``rts_direction`` RTS is the direction line."""

    port: int
    host: str = "127.0.0.1"
    rts_direction: bool = False


@dataclass(frozen=True)
class SerialPort:
    """A real serial device (a USB adapter on the robot's bus)."""

    device: str
    baud: int = DEFAULT_BAUD


Transport = Union[Pty, Tcp, Rfc2217, SerialPort]


class RealTimeRun:
    """One real-time run of ``scenario`` (a dict as TOML reads it, or a ``Scenario``):
    ``world`` serves its robot behind the bus (else the servos alone); ``trace`` records it;
    ``can_server`` bridges its CAN bus; ``sensor_id`` puts the limit-switch sensor node on
    the bus (None: none); ``duration_s`` ends it (None: until interrupted); ``verbose``
    receives a line for each injected fault and master mistake."""

    def __init__(self, scenario: Scenario | dict[str, Any], seed: int, *, world: bool = False,
                 ids: Sequence[int] | None = None, trace: str | None = None,
                 can_server: CanGateway | None = None, sensor_id: int | None = DEFAULT_ID,
                 duration_s: float | None = None,
                 verbose: Callable[[str], None] | None = None) -> None:
        sc = scenario_mod.parse(scenario)
        if duration_s is not None:
            scenario_mod.check_duration(duration_s, "duration_s")
        self.recorder = None
        if trace:
            from host_tools.trace.recorder import Recorder

            try:
                self.recorder = Recorder(trace, {**trace_metadata(sc, seed, EXTERNAL),
                                                 "command": "bus"},
                                         protocol=models.protocol(sc.bus.model))
            except OSError as exc:
                raise UserError(f"cannot write {trace}: {exc.strerror}") from None
        try:
            self.rig = RealTimeRig(sc, seed, world=world, ids=ids, recorder=self.recorder,
                                   can_server=can_server, sensor_id=sensor_id, verbose=verbose)
        except BaseException:
            self._close_trace()
            raise
        end_us = None if duration_s is None else int(round(duration_s * 1e6))
        self._injections: list[tuple[str, dict[str, Any], Callable[[str], None]]] = []
        self.server = serial_server.RealTimeServer(
            self.rig.bus, step_us=WORLD_STEP_US if self.rig.world is not None else None,
            on_tick=self._tick, end_us=end_us)

    def inject(self, kind: str, on_error: Callable[[str], None] | None = None,
               **params: Any) -> None:
        """A named fault while serving (any thread: ``hexhil bus --inject-stdin``), applied
        at the server's next tick, now or at ``at_s``; a bad one goes to ``on_error``."""
        self._injections.append((kind, params, on_error or (lambda line: None)))

    def _tick(self, t_us: int) -> None:
        while self._injections:
            kind, params, on_error = self._injections.pop(0)
            try:
                self.rig.core.inject(kind, **params)
            except UserError as exc:
                on_error(str(exc))
        self.rig.tick(t_us)

    def _close_trace(self) -> None:
        if self.recorder is not None:
            self.recorder.close()
            self.recorder = None

    def serve(self, transport: Transport, announce: Callable[[str], None]) -> dict[str, Any]:
        """Serve until the run's end, an interrupt (``KeyboardInterrupt``) or
        ``serial_server.Stop`` (SIGTERM); ``announce`` gets the address line (``pty: PATH``,
        ``tcp: ...``, ``rfc2217: ...``, ``port: ...``) once it is ready. The trace is
        complete on return; returns the summary (time served, body, faults, bus, master
        violations, pacing, and for RFC 2217 the client's line settings)."""
        try:
            if isinstance(transport, Rfc2217):
                from hil.servobus.rfc2217_server import serve_rfc2217

                serve_rfc2217(self.server, transport.port, transport.host, announce,
                                         transport.rts_direction)
            elif isinstance(transport, SerialPort):
                self.server.serve_port(transport.device, transport.baud, announce)
            elif isinstance(transport, Tcp):
                self.server.serve_tcp(transport.port, transport.host, announce)
            else:
                self.server.serve_pty(announce)
        except (KeyboardInterrupt, serial_server.Stop):
            pass
        except OSError as exc:
            raise UserError(str(exc)) from None
        finally:
            self.rig.close()
            self._close_trace()
        summary = self.rig.summary(self.server.pacing.summary())
        summary["client_bauds"] = list(self.server.client_bauds)
        return summary
