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
from types import MappingProxyType
from typing import Any, Callable, Mapping, Sequence, Union

from hexhil.hil import scenario as scenario_mod
from hexhil.hil.servobus import serial_server
from hexhil.hil.run.realtime_rig import RealTimeRig
from hexhil.hil.scenario import DEFAULT_BAUD, Scenario
from hexhil.hil.seams import CanGateway
from hexhil.hil.servobus.switch_node import DEFAULT_ID
from hexhil.hil.run_result import BodyDisplacement
from hexhil.lifecycle import Closing
from hexhil.trace.run_metadata import trace_metadata
from hexhil.protocol.dynamixel import models
from hexhil.protocol.errors import BadFile, UserError

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


class RealTimeRun(Closing):
    """One real-time run of ``scenario`` (a dict as TOML reads it, or a ``Scenario``):
    ``world`` serves its robot behind the bus (else the servos alone); ``trace`` records it;
    ``can_server`` bridges its CAN bus; ``sensor_id`` puts the limit-switch sensor node on
    the bus (None: none); ``duration_s`` ends it (None: until interrupted); ``verbose``
    receives a line for each injected fault and master mistake."""

    def __init__(self, scenario: Scenario | dict[str, Any], seed: int, *, world: bool = False,
                 ids: Sequence[int] | None = None, trace: str | None = None,
                 can_server: CanGateway | None = None, sensor_id: int | None = DEFAULT_ID,
                 duration_s: float | None = None,
                 verbose: Callable[[str], None] | None = None, overwrite: bool = False) -> None:
        sc = scenario_mod.parse(scenario)
        scenario_mod.check_seed(seed, "seed", params=("seed",))
        if duration_s is not None:
            scenario_mod.check_duration(duration_s, "duration_s")
        self.recorder = None
        if trace:
            from hexhil.trace.recorder import Recorder

            self.recorder = Recorder(trace, {**trace_metadata(sc, seed, EXTERNAL),
                                             "command": "bus"},
                                     protocol=models.protocol(sc.bus.model), overwrite=overwrite)
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

    def close(self) -> None:
        """Close the rig and the trace (complete as far as the run went); ``serve`` does it
        on its way out, so this is for a run that is never served."""
        rig = getattr(self, "rig", None)   # None until made (close() runs on a failed start)
        if rig is not None:
            rig.close()
            self.rig = None
        self._close_trace()

    def serve(self, transport: Transport, announce: Callable[[str], None]) -> "ServeResult":
        """Serve until the run's end, an interrupt (``KeyboardInterrupt``) or
        ``serial_server.Stop`` (SIGTERM); ``announce`` gets the address line (``pty: PATH``,
        ``tcp: ...``, ``rfc2217: ...``, ``port: ...``) once it is ready. The trace is
        complete on return; returns the summary (time served, body, faults, bus, master
        violations, pacing, and the client's line settings) as a ``ServeResult``."""
        try:
            if isinstance(transport, Rfc2217):
                from hexhil.hil.servobus.rfc2217_server import serve_rfc2217

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
        except UserError:   # a BadFile is an OSError too: already one line
            raise
        except OSError as exc:
            raise BadFile(str(exc)) from None
        finally:
            rig = self.rig
            self.close()
        return ServeResult.of(rig.summary(self.server.pacing.summary()), self.server.client_bauds)


@dataclass(frozen=True)
class ServeResult:
    """What a real-time run served, frozen when it ends; ``as_dict()`` is ``hexhil bus
    --json``'s summary. ``body`` and ``world_s`` are None without a world."""

    scenario: str | None
    seed: int
    served_s: float
    bus: Mapping[str, Any]            # the line's counters (packets, replies, bytes, ...)
    faults: Mapping[str, int]         # injected faults by kind
    switch_edges: int
    violations: Mapping[str, Any]     # the master's protocol mistakes (counts, first ones)
    pacing: Mapping[str, Any]         # lag against the wall clock, the host's apart
    sensor_node: Mapping[str, Any] | None
    client_bauds: tuple[int, ...]     # the rates the client set, in order
    body: BodyDisplacement | None = None
    world_s: float | None = None

    @classmethod
    def of(cls, summary: dict[str, Any], client_bauds: Sequence[int]) -> "ServeResult":
        frozen = {k: MappingProxyType(dict(v)) if isinstance(v, dict) else v
                  for k, v in summary.items() if k != "body"}
        body = summary.get("body")
        return cls(**frozen, client_bauds=tuple(client_bauds),
                   body=None if body is None else BodyDisplacement(**body))

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "scenario": self.scenario, "seed": self.seed, "served_s": self.served_s,
            "bus": dict(self.bus), "faults": dict(self.faults),
            "switch_edges": self.switch_edges, "violations": dict(self.violations),
            "pacing": dict(self.pacing),
            "sensor_node": None if self.sensor_node is None else dict(self.sensor_node),
            "client_bauds": list(self.client_bauds)}
        if self.body is not None:
            out["body"], out["world_s"] = self.body.as_dict(), self.world_s
        return out
