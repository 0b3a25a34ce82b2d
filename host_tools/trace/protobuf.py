"""Our protobuf messages (classes built at import, with the FileDescriptorSet Foxglove
needs), Foxglove's well-known ones, and hand-rolled encoders for the hot messages.

A run records about a thousand serial, Dynamixel and link messages per simulated second;
building protobuf objects cost ~2 us each, most of the recording overhead. The
``encode_*`` functions write the same bytes ``SerializeToString()`` does (fields in
number order, proto3 defaults omitted), which tests/test_recorder.py checks against the
generated classes.
"""
from __future__ import annotations

import functools
import struct
from typing import Any, Iterable, Mapping, Sequence

from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.JointStates_pb2 import JointStates
from foxglove_schemas_protobuf.Log_pb2 import Log
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from mcap_protobuf.schema import build_file_descriptor_set

from hexhil.protocol.dynamixel import v1 as dynamixel

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


# schema name -> message class, for every protobuf schema a trace of ours holds
CLASSES: dict[str, Any] = {cls.DESCRIPTOR.full_name: cls for cls in (
    *_CLASSES.values(), FrameTransform, FrameTransforms, JointStates, Log, SceneUpdate)}


def descriptor_set(schema_name: str) -> bytes:
    """The FileDescriptorSet stored as a protobuf schema's data."""
    return _HEXHIL_FDS if schema_name.startswith("hexhil.") else _foxglove_fds(schema_name)


@functools.cache
def _foxglove_fds(schema_name: str) -> bytes:
    """A Foxglove message's FileDescriptorSet (built once a process, a few ms)."""
    return build_file_descriptor_set(CLASSES[schema_name]).SerializeToString()


# -- hand-rolled protobuf for the hot messages --------------------------------------------

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
    return _transform(_timestamp_field(t_ns), _frame_names(parent, child), position_m,
                      quaternion_wxyz)


def _transform(stamp: bytes, names: bytes, position_m: Sequence[float],
               quaternion_wxyz: Sequence[float]) -> bytes:
    x, y, z = position_m
    w, qx, qy, qz = quaternion_wxyz
    return (stamp + names
            + _field_message(0x22, _field_double(0x09, x) + _field_double(0x11, y)
                             + _field_double(0x19, z))
            + _field_message(0x2A, _field_double(0x09, qx) + _field_double(0x11, qy)
                             + _field_double(0x19, qz) + _field_double(0x21, w)))


_FRAME_NAMES: dict[tuple[str, str], bytes] = {}  # (parent, child) as fields 2 and 3


def _frame_names(parent: str, child: str) -> bytes:
    names = _FRAME_NAMES.get((parent, child))
    if names is None:
        names = _FRAME_NAMES[(parent, child)] = (_field_bytes(0x12, parent.encode())
                                                 + _field_bytes(0x1A, child.encode()))
    return names


def encode_frame_transforms(t_ns: int, frames: Iterable[Sequence[Any]]) -> bytes:
    """``foxglove.FrameTransforms``: one transform per (child, parent, position_m,
    quaternion_wxyz), with one timestamp."""
    stamp = _timestamp_field(t_ns)
    return b"".join(_field_message(0x0A, _transform(stamp, _frame_names(parent, child), p, q))
                    for child, parent, p, q in frames)

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


def servo_row(s: Mapping[str, Any]) -> tuple:
    """A ``ServoState``'s fields in order (``hil.seams.SERVO_STATE_FIELDS``: id,
    position_rad, velocity_rad_s, load_frac, temperature_c, voltage_v, torque_enabled,
    moving, error); a missing key takes the proto3 default. Rows, not mappings, are what
    the recorder holds: they pickle at a third of the cost on the way to the encoding
    child."""
    g = s.get
    return (g("id", 0), g("position_rad", 0.0), g("velocity_rad_s", 0.0), g("load_frac", 0.0),
            g("temperature_c", 0.0), g("voltage_v", 0.0), bool(g("torque_enabled")),
            bool(g("moving")), g("error", 0))


def encode_servo_states(servos: Iterable[Mapping[str, Any]]) -> bytes:
    """``hexhil.ServoStates``; a missing key takes the proto3 default."""
    return encode_servo_rows([servo_row(s) for s in servos])


def encode_servo_rows(rows: Iterable[tuple]) -> bytes:
    """``hexhil.ServoStates`` of ``servo_row``s."""
    out = []
    for sid, p, v, load, temp, volt, torque, moving, err in rows:
        tail = ((b"\x38\x01" if torque else b"") + (b"\x40\x01" if moving else b"")
                + _field_uint(0x48, err))
        if 0 < sid < 0x80 and 0.0 not in (p, v, load, temp, volt):  # -0.0 == 0.0 too
            body = _PACK_SERVO(0x08, sid, 0x11, p, 0x19, v, 0x21, load, 0x29, temp,
                               0x31, volt) + tail
        else:   # the long way
            body = (_field_uint(0x08, sid) + _field_double(0x11, p) + _field_double(0x19, v)
                    + _field_double(0x21, load) + _field_double(0x29, temp)
                    + _field_double(0x31, volt) + tail)
        out.append(_field_message(0x0A, body))
    return b"".join(out)


_PACKET_HEADS: dict[tuple, tuple[bytes, bytes]] = {}  # (direction, code, ...) -> fields
_ID_FIELD = [_field_uint(0x10, i) for i in range(256)]


def encode_dynamixel_packet(direction: str, servo_id: int, code: int, params: bytes,
                            raw: bytes, codec: Any = dynamixel, status: bool | None = None
                            ) -> bytes:
    """``hexhil.DynamixelPacket``, with the instruction or error names filled in from the
    packet's protocol (``codec``: protocol/dynamixel/v1.py or v2.py). A status packet
    (``status``; by default what the servos send, ``"rx"``) has its error byte as
    ``code`` and its names in ``errors``."""
    key = (direction, code) if codec is dynamixel and status is None else \
        (direction, code, codec.__name__, status)
    heads = _PACKET_HEADS.get(key)
    if heads is None:
        if direction == "rx" if status is None else status:
            instruction, errors = "", ",".join(codec.error_names(code))
        else:
            instruction, errors = codec.INSTRUCTION_NAMES.get(code, "0x%02X" % code), ""
        heads = _PACKET_HEADS[key] = (
            _string_1(direction),
            _field_uint(0x18, code) + _field_bytes(0x22, instruction.encode())
            + _field_bytes(0x2A, errors.encode()))
    id_field = _ID_FIELD[servo_id] if servo_id < 256 else _field_uint(0x10, servo_id)
    n, r = len(params), len(raw)
    if n < 0x80 and 0 < r < 0x80:
        return heads[0] + id_field + heads[1] + (b"\x32" + _BYTE[n] + params if n else b"") + \
            b"\x3a" + _BYTE[r] + raw
    return heads[0] + id_field + heads[1] + _field_bytes(0x32, params) + _field_bytes(0x3A, raw)

