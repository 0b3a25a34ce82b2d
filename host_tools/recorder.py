"""The one recorder every run writes its MCAP trace through.

``Recorder(path, metadata)`` is handed to the simulator (``None`` means no recording);
each part reports what it sees with an integer virtual timestamp in microseconds:

==================  ==============================  ====================================
method              topic                           schema (encoding)
==================  ==============================  ====================================
``serial``          ``/serial``                     ``hexhil.SerialBytes`` (protobuf)
``can``             ``/can/raw``                    ``hexhil.CanFrame`` (protobuf)
(DBC-decoded)       ``/can/<frame name>``           ``hexhil.can.<frame name>`` (jsonschema)
``switch_edge``     ``/switches``                   ``hexhil.SwitchEdge`` (protobuf)
``telemetry``       ``/telemetry``                  ``hexhil.Telemetry`` (jsonschema)
``servo_state``     ``/servos``                     ``hexhil.ServoStates`` (protobuf)
``body_pose``       ``/body``                       ``foxglove.FrameTransform`` (protobuf)
``joints``          ``/joints``                     ``foxglove.JointStates`` (protobuf)
``fault``           ``/faults``                     ``foxglove.Log`` (protobuf)
``link``            ``/link``                       ``hexhil.LinkExchanges`` (protobuf)
==================  ==============================  ====================================

Why it is built this way:

* Foxglove plots protobuf and jsonschema messages without plugins; its well-known names
  are used where one exists (FrameTransform, JointStates, Log). CAN has no well-known
  schema, so frames are logged raw and, per DBC frame, decoded into plain numbers.
* Crash safety: messages are held for at most ``flush_interval_us`` of *virtual* time,
  then sorted into log-time order, written as one zstd chunk and flushed to the OS (at the
  next ``idle()`` call, at the same virtual time, when the owner calls it). A run killed
  with SIGKILL therefore loses at most the last window (0.5 s by default), which
  ``hexhil trace recover`` proves by reading the file without its summary.
* Determinism: nothing here reads the wall clock; the same run gives the same bytes.
* Cost: the parts hand over raw values (about 1 us a call) and the encoding (hand-rolled
  protobuf for the ~360 serial bursts a simulated second) is done in ``idle()``, which the
  simulator calls while the firmware computes, so on two or more cores it overlaps the
  firmware instead of adding to the run. What ``idle()`` has not done is done when the
  window is written. ``make bench`` measures what recording adds to a run. Each message
  costs its framing and index entry, so a serial burst carries its decoded Dynamixel
  packets (``SerialBytes.packets``) instead of a second topic repeating the bytes.
* ``/link`` holds every simulator-link request the firmware made and the reply it got
  (the firmware's whole view of the world), so ``hexhil replay`` can serve the replies
  back and compare the requests byte for byte. Nobody plots them, so each window's
  exchanges (about 200 a simulated second) go in one message, each with its own
  ``t_us``.
"""
from __future__ import annotations

import functools
import json
from importlib import metadata as _pkg_metadata
from operator import itemgetter
from pathlib import Path
from typing import Any, BinaryIO, Callable, Iterable, Mapping, Sequence

from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.JointStates_pb2 import JointStates
from foxglove_schemas_protobuf.Log_pb2 import Log
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
import struct
import zlib

import zstandard
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (Channel, Chunk, ChunkIndex, DataEnd, Footer, Header, MessageIndex,
                          Metadata, MetadataIndex, Schema, Statistics, SummaryOffset)
from mcap.writer import MCAP0_MAGIC
from mcap_protobuf.schema import build_file_descriptor_set

from protocol.errors import UserError
from protocol import can_frames, dynamixel
from protocol.can_frames import LEGS as LEG_NAMES  # bit order of tactile.switches

PROFILE = ""  # MCAP profile: none of the ROS profiles apply
METADATA_NAME = "hexhil"
DEFAULT_FLUSH_INTERVAL_US = 500_000  # well inside the "once per simulated second"

# Topics (the names are the API that trace tools, replay and estimate read).
T_SERIAL = "/serial"
T_CAN_RAW = "/can/raw"
T_CAN_PREFIX = "/can/"
T_SWITCHES = "/switches"
T_TELEMETRY = "/telemetry"
T_SERVOS = "/servos"
T_BODY = "/body"
T_JOINTS = "/joints"
T_FAULTS = "/faults"
T_LINK = "/link"

_F = descriptor_pb2.FieldDescriptorProto
_TYPES = {"string": _F.TYPE_STRING, "bytes": _F.TYPE_BYTES, "uint32": _F.TYPE_UINT32,
          "uint64": _F.TYPE_UINT64, "int64": _F.TYPE_INT64, "bool": _F.TYPE_BOOL,
          "double": _F.TYPE_DOUBLE}

# Our own protobuf messages: (name, [(field, type)]); a type naming another message here
# makes a repeated field of it.
_MESSAGES: list[tuple[str, list[tuple[str, str]]]] = [
    ("SerialBytes", [("direction", "string"), ("data", "bytes"), ("length", "uint32"),
                     ("packets", "DynamixelPacket")]),
    ("DynamixelPacket", [("direction", "string"), ("id", "uint32"), ("code", "uint32"),
                         ("instruction", "string"), ("errors", "string"),
                         ("params", "bytes"), ("raw", "bytes")]),
    ("CanFrame", [("direction", "string"), ("arbitration_id", "uint32"),
                  ("is_extended_id", "bool"), ("dlc", "uint32"), ("data", "bytes"),
                  ("name", "string")]),
    ("SwitchEdge", [("leg", "uint32"), ("leg_name", "string"), ("level", "bool"),
                    ("switches", "uint32")]),
    ("ServoState", [("id", "uint32"), ("position_rad", "double"),
                    ("velocity_rad_s", "double"), ("load_frac", "double"),
                    ("temperature_c", "double"), ("voltage_v", "double"),
                    ("torque_enabled", "bool"), ("moving", "bool"), ("error", "uint32")]),
    ("ServoStates", [("servos", "ServoState")]),
    ("LinkExchange", [("kind", "string"), ("request", "bytes"), ("reply", "bytes"),
                      ("t_us", "uint64")]),
    ("LinkExchanges", [("exchanges", "LinkExchange")]),
]


def _build_classes() -> tuple[dict[str, Any], bytes]:
    """Message classes for ``_MESSAGES`` and the FileDescriptorSet Foxglove needs."""
    fdp = descriptor_pb2.FileDescriptorProto(name="hexhil/trace.proto", package="hexhil",
                                             syntax="proto3")
    names = {n for n, _ in _MESSAGES}
    for name, fields in _MESSAGES:
        msg = fdp.message_type.add(name=name)
        for number, (fname, ftype) in enumerate(fields, start=1):
            if ftype in names:
                msg.field.add(name=fname, number=number, type=_F.TYPE_MESSAGE,
                              type_name=f".hexhil.{ftype}", label=_F.LABEL_REPEATED)
            else:
                msg.field.add(name=fname, number=number, type=_TYPES[ftype],
                              label=_F.LABEL_OPTIONAL)
    pool = descriptor_pool.DescriptorPool()
    fd = pool.Add(fdp)
    classes = {n: message_factory.GetMessageClass(pool.FindMessageTypeByName(f"hexhil.{n}"))
               for n in names}
    fds = descriptor_pb2.FileDescriptorSet()
    fds.file.add().CopyFrom(fdp)
    del fd
    return classes, fds.SerializeToString()


_CLASSES, _HEXHIL_FDS = _build_classes()
SerialBytes = _CLASSES["SerialBytes"]
DynamixelPacket = _CLASSES["DynamixelPacket"]
CanFrame = _CLASSES["CanFrame"]
SwitchEdge = _CLASSES["SwitchEdge"]
ServoState = _CLASSES["ServoState"]
ServoStates = _CLASSES["ServoStates"]
LinkExchange = _CLASSES["LinkExchange"]
LinkExchanges = _CLASSES["LinkExchanges"]



# -- hand-rolled protobuf for the hot messages --------------------------------------------
# A run records about a thousand serial, Dynamixel and link messages per simulated second;
# building protobuf objects cost ~2 us each, most of the recording overhead. These write
# the same bytes SerializeToString() does (fields in number order, proto3 defaults
# omitted), which tests/test_recorder.py checks against the generated classes.

def _varint(n: int) -> bytes:
    if n < 0x80:
        return _BYTE[n]
    out = bytearray()
    while n >= 0x80:
        out.append((n & 0x7F) | 0x80)
        n >>= 7
    out.append(n)
    return bytes(out)


_BYTE = [bytes((i,)) for i in range(256)]


def _field_bytes(tag: int, data: bytes) -> bytes:
    """A length-delimited field (string or bytes); empty means absent in proto3."""
    if not data:
        return b""
    n = len(data)
    return (_BYTE[tag] + _BYTE[n] if n < 0x80 else _BYTE[tag] + _varint(n)) + data


def _field_uint(tag: int, n: int) -> bytes:
    return _BYTE[tag] + _varint(n) if n else b""


_STRING_1: dict[str, bytes] = {}  # a string as field 1 (direction, kind), encoded once


def _string_1(s: str) -> bytes:
    field = _STRING_1.get(s)
    if field is None:
        field = _STRING_1[s] = _field_bytes(0x0A, s.encode())
    return field


def encode_serial_bytes(direction: str, data: bytes, packets: Sequence[bytes] = ()) -> bytes:
    """``hexhil.SerialBytes(direction, data, length=len(data), packets)``, each packet
    already encoded by ``encode_dynamixel_packet``."""
    n = len(data)
    if 0 < n < 0x80:  # every Dynamixel burst: one length byte, no helper calls
        out = _string_1(direction) + b"\x12" + _BYTE[n] + data + b"\x18" + _BYTE[n]
    else:
        out = _string_1(direction) + _field_bytes(0x12, data) + _field_uint(0x18, n)
    for p in packets:
        out += _field_message(0x22, p)
    return out


def encode_link_exchange(kind: str, request: bytes, reply: bytes, t_us: int) -> bytes:
    """One ``LinkExchange`` as a field of ``hexhil.LinkExchanges``; a window's message is
    its exchanges' fields one after another."""
    return _field_message(0x0A, _string_1(kind) + _field_bytes(0x12, request)
                          + _field_bytes(0x1A, reply) + _field_uint(0x20, t_us))


def encode_can_frame(direction: str, arb_id: int, is_extended_id: bool, data: bytes,
                     name: str) -> bytes:
    """``hexhil.CanFrame(direction, arbitration_id, is_extended_id, dlc=len(data), data,
    name)``."""
    return (_string_1(direction) + _field_uint(0x10, arb_id)
            + (b"\x18\x01" if is_extended_id else b"") + _field_uint(0x20, len(data))
            + _field_bytes(0x2A, data) + _field_bytes(0x32, name.encode()))


_ZERO8 = bytes(8)
_PACK_DOUBLE = struct.Struct("<d").pack


def _field_double(tag: int, value: float) -> bytes:
    """A double field; proto3 leaves out exactly +0.0 (-0.0 and NaN are written)."""
    b = _PACK_DOUBLE(value)
    return b"" if b == _ZERO8 else _BYTE[tag] + b


def _field_message(tag: int, body: bytes) -> bytes:
    """A set sub-message: written even when empty (the generated classes do the same)."""
    return _BYTE[tag] + _varint(len(body)) + body


def _timestamp_field(t_ns: int) -> bytes:
    """``google.protobuf.Timestamp`` as field 1 (Foxglove's ``timestamp``)."""
    seconds, nanos = divmod(t_ns, 1_000_000_000)
    return _field_message(0x0A, _field_uint(0x08, seconds) + _field_uint(0x10, nanos))


def encode_frame_transform(t_ns: int, parent: str, child: str,
                           position_m: Sequence[float], quaternion_wxyz: Sequence[float]) -> bytes:
    """``foxglove.FrameTransform`` with its timestamp, frames, translation and rotation."""
    x, y, z = position_m
    w, qx, qy, qz = quaternion_wxyz
    return (_timestamp_field(t_ns) + _field_bytes(0x12, parent.encode())
            + _field_bytes(0x1A, child.encode())
            + _field_message(0x22, _field_double(0x09, x) + _field_double(0x11, y)
                             + _field_double(0x19, z))
            + _field_message(0x2A, _field_double(0x09, qx) + _field_double(0x11, qy)
                             + _field_double(0x19, qz) + _field_double(0x21, w)))


_NAME_FIELDS: dict[str, bytes] = {}  # a joint name as JointState field 1, encoded once
_PACK_JOINT = struct.Struct("<BdBdBd").pack  # position, velocity, effort with their tags


def encode_joint_states(t_ns: int, names: Sequence[str], positions: Sequence[float],
                        velocities: Sequence[float], efforts: Sequence[float]) -> bytes:
    """``foxglove.JointStates``: name, position, velocity and effort per joint (a
    JointState's numbers have explicit presence: written when set, zero included)."""
    out = [_timestamp_field(t_ns)]
    for i in range(len(names)):
        name = _NAME_FIELDS.get(names[i])
        if name is None:
            name = _NAME_FIELDS[names[i]] = _field_bytes(0x0A, names[i].encode())
        out.append(_field_message(0x12, name + _PACK_JOINT(0x11, positions[i], 0x19,
                                                           velocities[i], 0x29, efforts[i])))
    return b"".join(out)


_PACK_SERVO = struct.Struct("<BBBdBdBdBdBd").pack  # id < 128 and five non-zero doubles


def encode_servo_states(servos: Iterable[Mapping[str, Any]]) -> bytes:
    """``hexhil.ServoStates``; a missing key takes the proto3 default."""
    out = []
    for s in servos:
        g = s.get
        sid, err = g("id", 0), g("error", 0)
        values = (g("position_rad", 0.0), g("velocity_rad_s", 0.0), g("load_frac", 0.0),
                  g("temperature_c", 0.0), g("voltage_v", 0.0))
        tail = ((b"\x38\x01" if g("torque_enabled") else b"")
                + (b"\x40\x01" if g("moving") else b"") + _field_uint(0x48, err))
        if 0 < sid < 0x80 and 0.0 not in values:  # -0.0 == 0.0 too: it takes the long way
            p, v, load, temp, volt = values
            body = _PACK_SERVO(0x08, sid, 0x11, p, 0x19, v, 0x21, load, 0x29, temp,
                               0x31, volt) + tail
        else:
            body = (_field_uint(0x08, sid) + _field_double(0x11, values[0])
                    + _field_double(0x19, values[1]) + _field_double(0x21, values[2])
                    + _field_double(0x29, values[3]) + _field_double(0x31, values[4]) + tail)
        out.append(_field_message(0x0A, body))
    return b"".join(out)


_PACKET_HEADS: dict[tuple[str, int], tuple[bytes, bytes]] = {}  # (direction, code) -> fields
_ID_FIELD = [_field_uint(0x10, i) for i in range(256)]


def encode_dynamixel_packet(direction: str, servo_id: int, code: int, params: bytes,
                            raw: bytes) -> bytes:
    """``hexhil.DynamixelPacket``, with the instruction or error names filled in."""
    heads = _PACKET_HEADS.get((direction, code))
    if heads is None:
        if direction == "rx":
            instruction, errors = "", ",".join(dynamixel.error_names(code))
        else:
            instruction, errors = dynamixel.INSTRUCTION_NAMES.get(code, "0x%02X" % code), ""
        heads = _PACKET_HEADS[(direction, code)] = (
            _string_1(direction),
            _field_uint(0x18, code) + _field_bytes(0x22, instruction.encode())
            + _field_bytes(0x2A, errors.encode()))
    id_field = _ID_FIELD[servo_id] if servo_id < 256 else _field_uint(0x10, servo_id)
    n, r = len(params), len(raw)
    if n < 0x80 and 0 < r < 0x80:
        return heads[0] + id_field + heads[1] + (b"\x32" + _BYTE[n] + params if n else b"") + \
            b"\x3a" + _BYTE[r] + raw
    return heads[0] + id_field + heads[1] + _field_bytes(0x32, params) + _field_bytes(0x3A, raw)


@functools.cache
def software_version() -> str:
    try:
        return _pkg_metadata.version("hexhil")
    except _pkg_metadata.PackageNotFoundError:
        return "unknown"


@functools.cache
def _dbc():
    """The project's DBC through cantools (loaded once a process: ~13 ms, as much as
    recording 10 s of a run), or None while protocol/hexhil.dbc is absent."""
    path = Path(dynamixel.__file__).with_name("hexhil.dbc")
    if not path.exists():
        return None
    import cantools

    return cantools.database.load_file(str(path))


@functools.cache
def _descriptor_set(cls: Any) -> bytes:
    """A Foxglove message's FileDescriptorSet (built once a process, a few ms)."""
    return build_file_descriptor_set(cls).SerializeToString()


@functools.cache
def _can_json_schema(msg: Any) -> str:
    """The JSON schema of one DBC frame's decoded signals, units in the descriptions."""
    props = {s.name: {"type": "number", "description": f"{s.comment or s.name} [{s.unit or '-'}]"}
             for s in msg.signals}
    props["direction"] = {"type": "string"}
    return json.dumps({"title": f"hexhil.can.{msg.name}", "type": "object",
                       "properties": props}, sort_keys=True)


def _to_json(values: Any) -> str:
    return _JSON_ENCODER.encode(values)


def _json_default(o: Any) -> Any:
    if isinstance(o, (bytes, bytearray)):
        return o.hex()
    if hasattr(o, "tolist"):  # numpy scalars and arrays
        return o.tolist()
    if hasattr(o, "value"):  # cantools NamedSignalValue
        return o.value
    return str(o)


# one encoder for the run (json.dumps with default= builds a new one per call)
_JSON_ENCODER = json.JSONEncoder(default=_json_default)


_MESSAGE_HEADER = struct.Struct("<BQHIQQ")  # opcode, length, channel, sequence, times


class _TraceWriter:
    """A lean MCAP writer: the stock ``mcap`` record classes for everything but the
    messages, which are packed straight into each chunk (the stock writer's ~5 us a
    message was most of the recording overhead). Schemas and channels go to the data
    section as they appear, so a file cut short keeps them ahead of its chunks."""

    def __init__(self, f: BinaryIO, library: str) -> None:
        self.f = f
        self.b = RecordBuilder()
        self.pos = 0
        self.zstd = zstandard.ZstdCompressor(level=1)
        self.schemas: list[Schema] = []
        self.channels: list[Channel] = []
        self.metadata_indexes: list[MetadataIndex] = []
        self.chunk_indexes: list[ChunkIndex] = []
        self.counts: dict[int, int] = {}
        self.messages = 0
        self.start_ns: int | None = None
        self.end_ns = 0
        self._write(MCAP0_MAGIC)
        Header(profile=PROFILE, library=library).write(self.b)
        self._emit()

    def _write(self, data: bytes) -> None:
        self.f.write(data)
        self.pos += len(data)

    def _emit(self) -> None:
        self._write(self.b.end())

    def schema(self, sid: int, name: str, encoding: str, data: bytes) -> None:
        rec = Schema(id=sid, name=name, encoding=encoding, data=data)
        rec.write(self.b)
        self._emit()
        self.schemas.append(rec)

    def channel(self, cid: int, topic: str, encoding: str, sid: int) -> None:
        rec = Channel(id=cid, topic=topic, message_encoding=encoding, metadata={},
                      schema_id=sid)
        rec.write(self.b)
        self._emit()
        self.channels.append(rec)
        self.counts[cid] = 0

    def metadata(self, name: str, values: dict[str, str]) -> None:
        offset = self.pos
        Metadata(name=name, metadata=values).write(self.b)
        length = self.b.count
        self._emit()
        self.metadata_indexes.append(MetadataIndex(offset=offset, length=length, name=name))

    def chunk(self, msgs: list[tuple[int, int, bytes]]) -> None:
        """One zstd chunk of (log_time_ns, channel_id, data) already in log-time order,
        then its message indexes; flushed to the OS."""
        pack = _MESSAGE_HEADER.pack
        parts: list[bytes] = []
        index: dict[int, list[int]] = {}  # channel -> [log_time, offset, log_time, ...]
        off = 0
        seq = self.messages
        for t, cid, data in msgs:
            n = len(data)
            parts.append(pack(Opcode.MESSAGE, 22 + n, cid, seq & 0xFFFFFFFF, t, t))
            parts.append(data)
            idx = index.get(cid)
            if idx is None:
                idx = index[cid] = []
            idx += (t, off)
            off += 31 + n
            seq += 1
        raw = b"".join(parts)
        comp = self.zstd.compress(raw)
        t0, t1 = msgs[0][0], msgs[-1][0]
        start = self.pos
        Chunk(compression="zstd", data=comp, message_start_time=t0, message_end_time=t1,
              uncompressed_crc=zlib.crc32(raw), uncompressed_size=len(raw)).write(self.b)
        chunk_length = self.b.count
        self._emit()
        # Message indexes packed by hand: the stock record writes each entry through
        # two calls (~1.5 us a message).
        offsets = {}
        records = []
        pos = self.pos
        counts = self.counts
        for cid in sorted(index):
            flat = index[cid]
            entries = struct.pack("<%dQ" % len(flat), *flat)
            offsets[cid] = pos
            records.append(struct.pack("<BQHI", Opcode.MESSAGE_INDEX, 6 + len(entries), cid,
                                       len(entries)))
            records.append(entries)
            pos += 15 + len(entries)
            counts[cid] += len(flat) // 2
        index_bytes = b"".join(records)
        index_length = len(index_bytes)
        self._write(index_bytes)
        self.chunk_indexes.append(ChunkIndex(
            message_start_time=t0, message_end_time=t1, chunk_start_offset=start,
            chunk_length=chunk_length, message_index_offsets=offsets,
            message_index_length=index_length, compression="zstd",
            compressed_size=len(comp), uncompressed_size=len(raw)))
        self.messages = seq
        self.start_ns = t0 if self.start_ns is None else min(self.start_ns, t0)
        self.end_ns = max(self.end_ns, t1)
        self.f.flush()

    def finish(self) -> None:
        """Data end, the summary (schemas, channels, statistics, chunk and metadata
        indexes, each group with its summary offset), the footer and the closing magic."""
        DataEnd(data_section_crc=0).write(self.b)
        self._emit()
        summary_start = self.pos
        b = RecordBuilder()
        offsets = []
        stats = Statistics(
            message_count=self.messages, schema_count=len(self.schemas),
            channel_count=len(self.channels), attachment_count=0,
            metadata_count=len(self.metadata_indexes), chunk_count=len(self.chunk_indexes),
            message_start_time=self.start_ns or 0, message_end_time=self.end_ns,
            channel_message_counts=dict(self.counts))
        for opcode, group in ((Opcode.SCHEMA, self.schemas), (Opcode.CHANNEL, self.channels),
                              (Opcode.STATISTICS, [stats]),
                              (Opcode.CHUNK_INDEX, self.chunk_indexes),
                              (Opcode.METADATA_INDEX, self.metadata_indexes)):
            if not group:
                continue
            group_start = summary_start + b.count
            for rec in group:
                rec.write(b)
            offsets.append(SummaryOffset(group_opcode=opcode, group_start=group_start,
                                         group_length=summary_start + b.count - group_start))
        offset_start = summary_start + b.count
        for o in offsets:
            o.write(b)
        summary = b.end()
        crc = zlib.crc32(summary)
        crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 20, summary_start, offset_start),
                         crc)
        self._write(summary)
        Footer(summary_start=summary_start, summary_offset_start=offset_start,
               summary_crc=crc).write(self.b)
        self._emit()
        self._write(MCAP0_MAGIC)
        self.f.flush()


class Recorder:
    """Writes one run to one MCAP file; see the module docstring for topics and schemas.

    ``metadata`` (scenario, seed, command...) is stored as the ``hexhil`` metadata record
    together with the software version. Times are integer virtual microseconds and should
    not go backwards by more than one flush window between calls.
    """

    def __init__(self, path: str | Path, metadata: Mapping[str, Any] | None = None, *,
                 flush_interval_us: int = DEFAULT_FLUSH_INTERVAL_US,
                 decode_serial: bool = True, decode_can: bool = True) -> None:
        self.path = Path(path)
        try:
            self._file: BinaryIO = open(self.path, "wb")
        except OSError as exc:
            raise UserError(f"{self.path}: cannot write trace ({exc.strerror})") from None
        self._writer = _TraceWriter(self._file, f"hexhil {software_version()}")
        meta = {"software_version": software_version()}
        for k, v in (metadata or {}).items():
            meta[str(k)] = v if isinstance(v, str) else json.dumps(v, sort_keys=True,
                                                                   default=_json_default)
        self._writer.metadata(METADATA_NAME, meta)
        self._flush_interval_us = int(flush_interval_us)
        self._window_end_us = self._flush_interval_us
        self._pending: list[tuple] = []  # (log_time_ns, encode, args) in call order
        self._out: list[tuple[int, int, bytes]] = []  # the first _done of them, encoded
        self._done = 0
        self._ready: list[tuple[int, int, bytes]] | None = None  # a closed window, unwritten
        self._idle_seen = False
        self._channels: dict[str, int] = {}
        self._schemas: dict[str, int] = {}
        self._parsers = {"tx": dynamixel.Parser(), "rx": dynamixel.Parser()} \
            if decode_serial else None
        self._dbc = _dbc() if decode_can else None
        self._can_kinds: dict[tuple[int, bool], tuple[str, Any, bool]] = {}
        self._links: bytearray | None = None  # this window's exchanges, encoded
        self._switches = 0
        self.messages = 0
        self.closed = False

    # -- plumbing -------------------------------------------------------------------------
    def _channel(self, topic: str, schema_name: str, encoding: str,
                 schema_data: Callable[[], bytes] | bytes) -> int:
        sid = self._schemas.get(schema_name)
        if sid is None:
            data = schema_data() if callable(schema_data) else schema_data
            sid = len(self._schemas) + 1
            self._writer.schema(sid, schema_name,
                                "protobuf" if encoding == "protobuf" else "jsonschema", data)
            self._schemas[schema_name] = sid
        cid = len(self._channels) + 1
        self._writer.channel(cid, topic, encoding, sid)
        self._channels[topic] = cid
        return cid

    def _proto_channel(self, topic: str, cls: Any) -> int:
        cid = self._channels.get(topic)
        if cid is not None:
            return cid
        full = cls.DESCRIPTOR.full_name
        if full.startswith("hexhil."):
            return self._channel(topic, full, "protobuf", _HEXHIL_FDS)
        return self._channel(topic, full, "protobuf", lambda: _descriptor_set(cls))

    def _json_channel(self, topic: str, schema_name: str, schema: Mapping[str, Any]) -> int:
        cid = self._channels.get(topic)
        if cid is not None:
            return cid
        return self._channel(topic, schema_name, "json",
                             json.dumps(schema, sort_keys=True).encode())

    def _defer(self, t_us: int, encode: Callable[..., None], args: tuple) -> None:
        """Hold the raw values; ``encode(out, t_ns, *args)`` appends the encoded messages
        in ``idle()`` or when the window is written, so a call costs about 1 us."""
        t_us = int(t_us)
        if t_us >= self._window_end_us:
            self._flush_window(t_us)
        self._pending.append((t_us * 1000, encode, args))

    def _flush_window(self, now_us: int) -> None:
        if self.closed:  # close() sets the window end to -1, so every later call lands here
            raise RuntimeError("recorder is closed")
        self._write_ready()
        msgs = self._encode_pending()
        if self._idle_seen:  # the owner calls idle() soon, off its critical path
            self._ready = msgs
        else:
            self._write_chunk(msgs)
        step = self._flush_interval_us
        self._window_end_us = (now_us // step + 1) * step

    def idle(self, budget: int) -> None:
        """Do a little of the held work: write a closed window, or encode up to ``budget``
        held messages. The simulator calls this while it waits for the firmware, so the
        encoding overlaps the firmware's computing instead of adding to it; the bytes
        written do not depend on when (or whether) it is called."""
        self._idle_seen = True
        if self._ready is not None:
            self._write_ready()
            return
        if not budget:
            return
        pending, out, i = self._pending, self._out, self._done
        for t, encode, args in pending[i:i + budget]:
            encode(out, t, *args)
        self._done = min(i + budget, len(pending))

    def flush(self) -> None:
        """Write the held messages in log-time order as one chunk and hand it to the OS."""
        self._write_ready()
        self._write_chunk(self._encode_pending())

    def _write_ready(self) -> None:
        if self._ready is not None:
            msgs, self._ready = self._ready, None
            self._write_chunk(msgs)

    def _encode_pending(self) -> list[tuple[int, int, bytes]]:
        """The held messages encoded, as (log_time_ns, channel, data) in log-time order."""
        pending, out = self._pending, self._out
        for t, encode, args in pending[self._done:]:  # call order: parsers see bytes in order
            encode(out, t, *args)
        self._pending, self._out, self._done = [], [], 0
        self._links = None
        out.sort(key=itemgetter(0))  # stable: equal times keep call order
        return out

    def _write_chunk(self, msgs: list[tuple[int, int, bytes]]) -> None:
        if msgs:
            self._writer.chunk(msgs)
            self.messages = self._writer.messages

    def advance(self, t_us: int) -> None:
        """Tell the recorder virtual time has reached ``t_us`` (flushes a finished window)."""
        if int(t_us) >= self._window_end_us and not self.closed:
            self._flush_window(int(t_us))

    def close(self) -> None:
        """Write everything and the MCAP summary; the file is complete after this."""
        if self.closed:
            return
        self._write_ready()
        msgs = self._encode_pending()
        if self._parsers is not None:  # packets hidden behind a bad header, found at the end
            for direction, parser in self._parsers.items():
                late = [encode_dynamixel_packet(direction, p.id, p.code, p.params, p.raw)
                        for p in parser.flush()]
                if late:  # on a burst of no new bytes at the last serial time
                    msgs.append((self._last_serial_ns, self._channels[T_SERIAL],
                                 encode_serial_bytes(direction, b"", late)))
            msgs.sort(key=itemgetter(0))
        self._write_chunk(msgs)
        self._writer.finish()
        self._file.close()
        self.closed = True
        self._window_end_us = -1

    def __enter__(self) -> "Recorder":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # -- what the parts record ------------------------------------------------------------
    _last_serial_ns = 0

    def serial(self, t_us: int, direction: str, data: bytes) -> None:
        """Raw bytes on the servo line (``"tx"`` master->servos, ``"rx"`` servos->master),
        with the Dynamixel packets they complete decoded beside them."""
        self._defer(t_us, self._encode_serial, (direction, bytes(data)))

    def _encode_serial(self, out: list, t: int, direction: str, data: bytes) -> None:
        cid = self._channels.get(T_SERIAL) or self._proto_channel(T_SERIAL, SerialBytes)
        out.append((t, cid, encode_serial_bytes(direction, data, self._packets(t, direction,
                                                                               data))))
        self._last_serial_ns = t

    def _packets(self, t: int, direction: str, data: bytes) -> list[bytes]:
        """The packets ``data`` completes, encoded (``data`` may end or start one)."""
        parser = self._parsers.get(direction) if self._parsers is not None else None
        if parser is None:
            return []
        n = len(data)
        if (not parser.pending() and n >= 6 and data[0] == 0xFF and data[1] == 0xFF
                and data[2] != 0xFF and data[3] + 4 == n
                and (~sum(data[2:n - 1])) & 0xFF == data[n - 1]):
            # one whole valid packet, nothing held: what push() would find, ~20x faster
            return [encode_dynamixel_packet(direction, data[2], data[4], data[5:n - 1], data)]
        found = []
        t_us = t // 1000
        for b in data:
            if parser.push(b, t_us):
                end = dynamixel.PARAMS_OFFSET + parser.nparams
                buf = parser.buf
                found.append(encode_dynamixel_packet(
                    direction, parser.id, parser.code,
                    bytes(buf[dynamixel.PARAMS_OFFSET:end]), bytes(buf[0:end + 1])))
        return found

    def can(self, t_us: int, arb_id: int, data: bytes, direction: str = "tx",
            is_extended_id: bool = False) -> None:
        """One CAN frame: raw on ``/can/raw`` and, if the DBC knows it, its signals in SI
        units on ``/can/<frame name>``. ``direction`` names who sent it relative to the
        firmware: ``"tx"`` firmware->bus, ``"rx"`` bus->firmware."""
        self._defer(t_us, self._encode_can, (arb_id, bytes(data), direction, is_extended_id))

    def _encode_can(self, out: list, t: int, arb_id: int, data: bytes, direction: str,
                    is_extended_id: bool) -> None:
        kind = self._can_kinds.get((arb_id, is_extended_id))
        if kind is None:
            kind = self._can_kinds[(arb_id, is_extended_id)] = self._can_kind(arb_id,
                                                                             is_extended_id)
        name, msg, ours = kind
        out.append((t, self._proto_channel(T_CAN_RAW, CanFrame),
                    encode_can_frame(direction, arb_id, is_extended_id, data, name)))
        if msg is None:
            return
        try:
            if ours:
                # our frames: protocol/can_frames.py, which tests/test_can_frames.py holds
                # to the DBC through cantools for every frame; ~10x faster than cantools
                signals = can_frames.decode(arb_id, data)[1]
            else:
                signals = msg.decode(data, decode_choices=False)
        except Exception:  # a frame the DBC cannot decode stays raw only
            return
        topic = T_CAN_PREFIX + name
        cid = self._channels.get(topic)
        if cid is None:
            cid = self._channel(topic, f"hexhil.can.{name}", "json",
                                _can_json_schema(msg).encode())
        signals["direction"] = direction
        out.append((t, cid, _to_json(signals).encode()))

    def _can_kind(self, arb_id: int, is_extended_id: bool) -> tuple[str, Any, bool]:
        """(DBC name or "", the DBC message or None, whether protocol/can_frames knows it)."""
        if self._dbc is None or is_extended_id:
            return "", None, False
        try:
            msg = self._dbc.get_message_by_frame_id(arb_id)
        except KeyError:
            return "", None, False
        return msg.name, msg, can_frames.BY_ID.get(arb_id) == msg.name

    def switch_edge(self, t_us: int, leg: int, level: bool) -> None:
        """A tactile limit switch changed (leg 0..5 in ``LEG_NAMES`` order; True = pressed)."""
        if level:
            self._switches |= 1 << leg
        else:
            self._switches &= ~(1 << leg)
        self._defer(t_us, self._encode_switch_edge, (leg, bool(level), self._switches))

    def _encode_switch_edge(self, out: list, t: int, leg: int, level: bool, switches: int
                            ) -> None:
        out.append((t, self._proto_channel(T_SWITCHES, SwitchEdge), SwitchEdge(
            leg=leg, leg_name=LEG_NAMES[leg] if leg < len(LEG_NAMES) else "", level=level,
            switches=switches).SerializeToString()))

    def telemetry(self, t_us: int, values: Mapping[str, Any]) -> None:
        """Free-form firmware telemetry (flat dict of numbers/strings) on ``/telemetry``."""
        self._defer(t_us, self._encode_telemetry, (dict(values),))

    def _encode_telemetry(self, out: list, t: int, values: dict[str, Any]) -> None:
        cid = self._json_channel(T_TELEMETRY, "hexhil.Telemetry",
                                 {"title": "hexhil.Telemetry", "type": "object"})
        out.append((t, cid, json.dumps(values, sort_keys=True,
                                       default=_json_default).encode()))

    def servo_state(self, t_us: int, servos: Iterable[Mapping[str, Any]]) -> None:
        """Emulated servo state, one message for all servos. Each mapping may hold ``id``,
        ``position_rad``, ``velocity_rad_s``, ``load_frac``, ``temperature_c``,
        ``voltage_v``, ``torque_enabled``, ``moving``, ``error``."""
        self._defer(t_us, self._encode_servo_state, ([dict(s) for s in servos],))

    def _encode_servo_state(self, out: list, t: int, servos: list[dict[str, Any]]) -> None:
        out.append((t, self._proto_channel(T_SERVOS, ServoStates), encode_servo_states(servos)))

    def body_pose(self, t_us: int, position_m: Sequence[float],
                  quaternion_wxyz: Sequence[float], parent: str = "world",
                  child: str = "body") -> None:
        """Ground-truth body pose as ``foxglove.FrameTransform`` (Foxglove's 3D panel)."""
        self._defer(t_us, self._encode_body_pose,
                    (tuple(map(float, position_m)), tuple(map(float, quaternion_wxyz)),
                     parent, child))

    def _encode_body_pose(self, out: list, t: int, position_m: tuple[float, ...],
                          quaternion_wxyz: tuple[float, ...], parent: str, child: str) -> None:
        out.append((t, self._proto_channel(T_BODY, FrameTransform),
                    encode_frame_transform(t, parent, child, position_m, quaternion_wxyz)))

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
        out.append((t, self._proto_channel(T_JOINTS, JointStates),
                    encode_joint_states(t, names, positions, velocities, efforts)))

    def fault(self, t_us: int, name: str, detail: str = "") -> None:
        """An injected fault (or one the firmware reported) as a ``foxglove.Log`` entry."""
        self._defer(t_us, self._encode_fault, (name, detail))

    def _encode_fault(self, out: list, t: int, name: str, detail: str) -> None:
        msg = Log(level=Log.WARNING, name=name, message=detail or name)
        msg.timestamp.FromNanoseconds(t)
        out.append((t, self._proto_channel(T_FAULTS, Log), msg.SerializeToString()))

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
        links += encode_link_exchange(kind, request, reply, t // 1000)

    def _encode_links(self, out: list, t: int, links: bytearray) -> None:
        """The window's one message; its exchanges are appended to ``links`` as they are
        encoded, all before the window is written."""
        cid = self._channels.get(T_LINK) or self._proto_channel(T_LINK, LinkExchanges)
        out.append((t, cid, links))


def open_recorder(path: str | Path | None, metadata: Mapping[str, Any] | None = None,
                  **kwargs: Any) -> Recorder | None:
    """A Recorder for ``--out PATH``, or None when no path was given."""
    return Recorder(path, metadata, **kwargs) if path else None
