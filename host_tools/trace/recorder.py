"""The one recorder every run writes its MCAP trace through.

``Recorder(path, metadata)`` is handed to the simulator (``None`` means no recording);
each part reports what it sees with an integer virtual timestamp in microseconds, on the
topics ``hexhil.trace.topics`` lists.

Why it is built this way:

* Crash safety: messages are held for at most ``flush_interval_us`` of *virtual* time,
  then sorted into log-time order, written as one zstd chunk and flushed to the OS (at the
  next ``idle()`` call, at the same virtual time, when the owner calls it). A run killed
  with SIGKILL therefore loses at most the last window (0.5 s by default), which
  ``hexhil trace recover`` proves by reading the file without its summary. The file is
  ``TARGET.partial``, locked, until ``close()`` renames it (host_tools/trace/target.py).
* Determinism: nothing here reads the wall clock; the same run gives the same bytes.
* Cost: the parts hand over raw values (about 1 us a call) and the encoding (hand-rolled
  protobuf for the ~360 serial bursts a simulated second) is done off the run's critical
  path (host_tools/trace/windows.py ``EncodeIn``): by default in a forked child that gets
  each closed window, or in ``idle()``, which the simulator calls while a firmware in its
  own process computes; what ``idle()`` has not done is done when the window is written.
  ``make bench`` measures what recording adds to a run. Each message costs its framing
  and index entry, so a serial burst carries its decoded Dynamixel
  packets (``SerialBytes.packets``) instead of a second topic repeating the bytes, decoded
  in the line's protocol (``protocol``: host_tools/dynamixel/decode/, the same schema for
  Protocol 1.0 and 2.0).
* ``/link`` holds every simulator-link request the firmware made and the reply it got
  (the firmware's whole view of the world), so ``hexhil replay`` can serve the replies
  back and compare the requests byte for byte. Nobody plots them, so each window's
  exchanges (about 200 a simulated second) go in one message, each with its own
  ``t_us``.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Sequence

from hexhil.trace import protobuf as pb
from hexhil.trace.can_signals import CanSignals, json_default, json_schema, to_json
from hexhil.trace import scene_encoding as scene_msgs
from hexhil.trace.topics import (CAN_SCHEMA_PREFIX, T_BODY, T_CAN_PREFIX,
                                     T_CAN_RAW, T_FAULTS, T_JOINTS, T_LINK, T_SCENE,
                                     T_SCENE_FORCES, T_SCENE_FRAMES, T_SERIAL, T_SERVOS,
                                     T_SWITCHES, T_TELEMETRY, T_VIOLATIONS)
from hexhil.trace.channels import Channels
from hexhil.trace.windows import EncodeIn, Encoded, HeldWindows
from hexhil.dynamixel.decode import DECODERS
from hexhil.hil.servobus import serial_stream
from hexhil.hil.seams import HeldSample
from hexhil.protocol.can_frames import LEGS as LEG_NAMES  # bit order of tactile.switches

DEFAULT_FLUSH_INTERVAL_US = 500_000  # well inside the "once per simulated second"


class Recorder(HeldWindows):
    """Writes one run to one MCAP file, on the topics ``hexhil.trace.topics`` lists.

    ``metadata`` (scenario, seed, command...) is stored as the ``hexhil`` metadata record
    together with the software version. Times are integer virtual microseconds and should
    not go backwards by more than one flush window between calls.
    """

    def __init__(self, path: str | Path, metadata: Mapping[str, Any] | None = None, *,
                 flush_interval_us: int = DEFAULT_FLUSH_INTERVAL_US,
                 decode_serial: bool = True, decode_can: bool = True, live: Any = None,
                 protocol: int = 1, overwrite: bool = False,
                 encode_in: EncodeIn = EncodeIn.CHILD_PROCESS) -> None:
        super().__init__(path, metadata, flush_interval_us, live, overwrite)
        self._channels = Channels(self._writer, live, self._write_failed)
        # /serial's bytes cut into the packets of the line's Dynamixel protocol
        self._parsers = {d: DECODERS[protocol].TracePackets(d) for d in ("tx", "rx")} \
            if decode_serial else None
        self._can = CanSignals(decode_can)
        self._links: bytearray | None = None  # this window's exchanges, encoded
        self._switches = 0
        self._begin(encode_in)

    def _new_window(self) -> None:
        self._links = None

    def _last(self, msgs: Encoded) -> None:
        if self._parsers is not None:  # packets hidden behind a bad header, found at the end
            for direction, parser in self._parsers.items():
                late = parser.flush()
                if late:  # on a burst of no new bytes at the last serial time
                    msgs.append((self._last_serial_ns, self._channels.ids[T_SERIAL],
                                 pb.encode_serial_bytes(direction, b"", late)))

    def __enter__(self) -> "Recorder":
        return self

    # -- what the parts record ------------------------------------------------------------
    _last_serial_ns = 0

    def serial(self, t_us: int, direction: str, data: bytes) -> None:
        """Raw bytes on the servo line (``"tx"`` master->servos, ``"rx"`` servos->master),
        with the Dynamixel packets they complete decoded beside them."""
        self._defer(t_us, self._encode_serial, (direction, bytes(data)))

    def serial_stream(self, stream: bytes, lens: Sequence[int]) -> None:
        """``serial`` for each record of a serial stream (hil/servobus/serial_stream.py), held
        as one value while the records are in one window."""
        if serial_stream.last_t_us(stream, lens) >= self._window_end_us:
            for t_us, direction, data in serial_stream.records(stream, lens):
                self.serial(t_us, direction, data)
            return
        t_us = serial_stream.HEAD.unpack_from(stream, 0)[0]
        self._defer(t_us, self._encode_serial_stream, (stream, bytes(lens)))

    def _encode_serial_stream(self, out: list, _t: int, stream: bytes, lens: bytes) -> None:
        for t_us, direction, data in serial_stream.records(stream, lens):
            self._encode_serial(out, t_us * 1000, direction, data)

    def _encode_serial(self, out: list, t: int, direction: str, data: bytes) -> None:
        cid = self._channels.of(T_SERIAL)
        out.append((t, cid, pb.encode_serial_bytes(direction, data, self._packets(t, direction,
                                                                               data))))
        self._last_serial_ns = t

    def _packets(self, t: int, direction: str, data: bytes) -> list[bytes]:
        """The packets ``data`` completes, encoded (``data`` may end or start one)."""
        parser = self._parsers.get(direction) if self._parsers is not None else None
        return parser.feed(data, t // 1000) if parser is not None else []

    def can(self, t_us: int, arb_id: int, data: bytes, direction: str = "tx",
            is_extended_id: bool = False) -> None:
        """One CAN frame: raw on ``/can/raw`` and, if the DBC knows it, its signals in SI
        units on ``/can/<frame name>``. ``direction`` names who sent it relative to the
        firmware: ``"tx"`` firmware->bus, ``"rx"`` bus->firmware."""
        self._defer(t_us, self._encode_can, (arb_id, bytes(data), direction, is_extended_id))

    def _encode_can(self, out: list, t: int, arb_id: int, data: bytes, direction: str,
                    is_extended_id: bool) -> None:
        name, msg, signals = self._can.decode(arb_id, data, is_extended_id)
        out.append((t, self._channels.of(T_CAN_RAW),
                    pb.encode_can_frame(direction, arb_id, is_extended_id, data, name)))
        if signals is None:
            return
        topic = T_CAN_PREFIX + name
        cid = self._channels.ids.get(topic)
        if cid is None:
            cid = self._channels.add(topic, CAN_SCHEMA_PREFIX + name, "json",
                                lambda: json_schema(msg).encode())
        signals["direction"] = direction
        out.append((t, cid, to_json(signals).encode()))

    def switch_edge(self, t_us: int, leg: int, level: bool) -> None:
        """A tactile limit switch changed (leg 0..5 in ``LEG_NAMES`` order; True = pressed)."""
        if level:
            self._switches |= 1 << leg
        else:
            self._switches &= ~(1 << leg)
        self._defer(t_us, self._encode_switch_edge, (leg, bool(level), self._switches))

    def _encode_switch_edge(self, out: list, t: int, leg: int, level: bool, switches: int
                            ) -> None:
        out.append((t, self._channels.of(T_SWITCHES), pb.SwitchEdge(
            leg=leg, leg_name=LEG_NAMES[leg] if leg < len(LEG_NAMES) else "", level=level,
            switches=switches).SerializeToString()))

    def telemetry(self, t_us: int, values: Mapping[str, Any]) -> None:
        """Free-form firmware telemetry (flat dict of numbers/strings) on ``/telemetry``."""
        self._defer(t_us, self._encode_telemetry, (dict(values),))

    def _encode_telemetry(self, out: list, t: int, values: dict[str, Any]) -> None:
        self._encode_json(out, t, T_TELEMETRY, values)

    def _encode_json(self, out: list, t: int, topic: str, values: dict[str, Any]) -> None:
        cid = self._channels.of(topic)
        out.append((t, cid, json.dumps(values, sort_keys=True, default=json_default).encode()))

    def servo_state(self, t_us: int, servos: Iterable[Mapping[str, Any] | tuple]) -> None:
        """Emulated servo state, one message for all servos. Each mapping may hold ``id``,
        ``position_rad``, ``velocity_rad_s``, ``load_frac``, ``temperature_c``,
        ``voltage_v``, ``torque_enabled``, ``moving``, ``error``; a tuple holds all of
        them in that order (``hil.seams.SERVO_STATE_FIELDS``); a ``HeldSample`` of such
        tuples is held as it is."""
        self._defer(t_us, self._encode_servo_state,
                    (servos if isinstance(servos, HeldSample) else
                     [s if type(s) is tuple else pb.servo_row(s) for s in servos],))

    def _encode_servo_state(self, out: list, t: int, rows: Sequence[tuple]) -> None:
        out.append((t, self._channels.of(T_SERVOS), pb.encode_servo_rows(rows)))

    def body_pose(self, t_us: int, position_m: Sequence[float],
                  quaternion_wxyz: Sequence[float], parent: str = "world",
                  child: str = "body") -> None:
        """Ground-truth body pose as ``foxglove.FrameTransform`` (Foxglove's 3D panel)."""
        self._defer(t_us, self._encode_body_pose,
                    (tuple(map(float, position_m)), tuple(map(float, quaternion_wxyz)),
                     parent, child))

    def _encode_body_pose(self, out: list, t: int, position_m: tuple[float, ...],
                          quaternion_wxyz: tuple[float, ...], parent: str, child: str) -> None:
        out.append((t, self._channels.of(T_BODY),
                    pb.encode_frame_transform(t, parent, child, position_m, quaternion_wxyz)))

    def joints(self, t_us: int, names: Sequence[str], positions_rad: Sequence[float],
               velocities_rad_s: Sequence[float] | None = None,
               efforts_nm: Sequence[float] | None = None) -> None:
        """Ground-truth joint states as ``foxglove.JointStates``."""
        n = len(names)
        zeros = [0.0] * n
        self._defer(t_us, self._encode_joints,
                    (list(names), [float(v) for v in positions_rad],
                     [float(v) for v in (velocities_rad_s if velocities_rad_s is not None
                                         else zeros)],
                     [float(v) for v in (efforts_nm if efforts_nm is not None else zeros)]))

    def _encode_joints(self, out: list, t: int, names: list[str], positions: list[float],
                       velocities: list[float], efforts: list[float]) -> None:
        out.append((t, self._channels.of(T_JOINTS),
                    pb.encode_joint_states(t, names, positions, velocities, efforts)))

    def fault(self, t_us: int, name: str, detail: str = "") -> None:
        """An injected fault (or one the firmware reported) as a ``foxglove.Log`` entry."""
        self._defer(t_us, self._encode_fault, (name, detail))

    def _encode_fault(self, out: list, t: int, name: str, detail: str) -> None:
        msg = pb.Log(level=pb.Log.WARNING, name=name, message=detail or name)
        msg.timestamp.FromNanoseconds(t)
        out.append((t, self._channels.of(T_FAULTS), msg.SerializeToString()))

    def violation(self, t_us: int, kind: str, detail: str) -> None:
        """A bus master's protocol mistake (hil/servobus/master_check.py) on ``/bus/violations``."""
        self._defer(t_us, self._encode_json, (T_VIOLATIONS, {"kind": kind, "detail": detail}))

    def scene(self, t_us: int, shapes: Sequence[Any]) -> None:
        """The 3D scene's geometry (``hil.world.scene.Shape``) on ``/scene``: all of it
        once, then the shapes that changed (an entity replaces the one of its id)."""
        self._defer(t_us, self._encode_scene, (T_SCENE, scene_msgs.encode_shapes, list(shapes)))

    def scene_frames(self, t_us: int, frames: Sequence[Any]) -> None:
        """The moving frames' poses (``hil.world.scene.Frame``: id, parent, position,
        quaternion), or a ``hil.world.scene_values.JointFrames``."""
        self._defer(t_us, self._encode_scene,
                    (T_SCENE_FRAMES, pb.encode_frame_transforms, _plain(frames)))

    def scene_forces(self, t_us: int, arrows: Sequence[Any]) -> None:
        """Contact forces as arrows (``hil.world.scene.Arrow``), or a
        ``hil.world.scene_values.ContactForces``."""
        self._defer(t_us, self._encode_scene,
                    (T_SCENE_FORCES, scene_msgs.encode_arrows, _plain(arrows)))

    def _encode_scene(self, out: list, t: int, topic: str,
                      encode: Callable[[int, list], bytes], values: list) -> None:
        out.append((t, self._channels.of(topic), encode(t, values)))

    def link(self, t_us: int, request: bytes, reply: bytes, kind: str = "") -> None:
        """One simulator-link exchange: the firmware's request and the host's reply, at the
        virtual time the request was answered (what ``hexhil replay`` serves back). A
        window's exchanges are written as one message at the first one's time."""
        t_us = int(t_us)
        if t_us >= self._window_end_us:
            self._flush_window(t_us)
        links = self._links
        if links is None:
            links = self._links = bytearray()
            self._defer(t_us, self._encode_links, (links,))
        self._defer(t_us, self._encode_link, (links, kind, bytes(request), bytes(reply)))

    def _encode_link(self, _out: list, t: int, links: bytearray, kind: str, request: bytes,
                     reply: bytes) -> None:
        links += pb.encode_link_exchange(kind, request, reply, t // 1000)

    def _encode_links(self, out: list, t: int, links: bytearray) -> None:
        """The window's one message; its exchanges are appended to ``links`` as they are
        encoded, all before the window is written."""
        cid = self._channels.of(T_LINK)
        out.append((t, cid, links))


def _plain(items: Sequence[Sequence[Any]]) -> Sequence[tuple]:
    """NamedTuples as plain tuples: the held values may go to the encoding child pickled,
    where a NamedTuple costs a Python call each (the scene made 45 % of a window's pickle).
    A ``HeldSample`` stays as it is: it pickles as the raw values it is made from, and its
    items are made where it is encoded."""
    if isinstance(items, HeldSample):
        return items
    return [tuple(v) for v in items]


def open_recorder(path: str | Path | None, metadata: Mapping[str, Any] | None = None,
                  **kwargs: Any) -> Recorder | None:
    """A Recorder for ``--out PATH`` (``overwrite=True`` for ``--overwrite``), or None when
    no path was given."""
    return Recorder(path, metadata, **kwargs) if path else None
