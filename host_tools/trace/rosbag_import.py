"""A ROS 2 bag -> our topics, through a small mapping file (``hexhil trace import --as
rosbag2 --map MAP.toml``), read with the pure-Python ``rosbags`` (sqlite3 or MCAP storage,
CDR; a type the bag carries its definition of is registered from it).

Each ``[topics."/bag/topic"]`` table says what the topic is (``as``) and, where its type is
not the usual one, which fields hold the values::

    [topics."/joint_states"]      # sensor_msgs/msg/JointState -> /joints
    as = "joints"
    [topics."/foot_switches"]     # an integer (bit i = leg i, LF LM LH RF RM RH) -> /switches
    as = "switches"
    field = "data"
    [topics."/can_rx"]            # id and data fields (can_msgs/msg/Frame's) -> /can/raw
    as = "can"
    direction = "rx"              # "rx": for the firmware (the default); "tx": its own

Times are the bag's receive times, t = 0 at the first message of a mapped topic.
"""
from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Any, Callable

from hexhil.trace.reader import why
from hexhil.protocol.errors import BadValue, UserError


class TopicAs(str, Enum):
    JOINTS = "joints"
    SWITCHES = "switches"
    CAN = "can"


KEYS = {TopicAs.JOINTS: ("as", "names", "positions", "velocities", "efforts"),
        TopicAs.SWITCHES: ("as", "field"),
        TopicAs.CAN: ("as", "id", "data", "extended", "direction")}
DEFAULTS = {"names": "name", "positions": "position", "velocities": "velocity",
            "efforts": "effort", "field": "data", "id": "id", "data": "data",
            "extended": "is_extended"}
LEGS = 6


def _field(msg: Any, path: str, topic: str) -> Any:
    """``msg.a.b`` for the dotted ``path``, or a one-line error naming the fields there are."""
    value = msg
    for part in path.split("."):
        if not hasattr(value, part):
            fields = sorted(getattr(type(value), "__dataclass_fields__", {}) or
                            [k for k in dir(value) if not k.startswith("_")])
            raise BadValue(f"{topic}: its messages have no field {path!r} "
                           f"(fields: {', '.join(fields)})")
        value = getattr(value, part)
    return value


def _topic_specs(maps: dict[str, Any], where: str) -> dict[str, dict[str, Any]]:
    topics = maps.get("topics")
    if not isinstance(topics, dict) or not topics:
        raise BadValue(f"{where}: a rosbag2 import needs map_path, a TOML file whose "
                       "[topics.\"/name\"] tables say what each topic is (as = "
                       f"{', '.join(t.value for t in TopicAs)})", params=("map_path",))
    specs = {}
    for name, spec in topics.items():
        if not isinstance(spec, dict) or "as" not in spec:
            raise BadValue(f"{where}: topic {name} needs as = "
                           f"{' | '.join(repr(t.value) for t in TopicAs)}")
        try:
            kind = TopicAs(spec["as"])
        except ValueError:
            raise BadValue(f"{where}: topic {name}: unknown as = {spec['as']!r} (one of "
                           f"{', '.join(t.value for t in TopicAs)})") from None
        bad = sorted(set(spec) - set(KEYS[kind]))
        if bad:
            raise BadValue(f"{where}: topic {name}: unknown key(s) {', '.join(bad)} for "
                           f"as = {kind.value!r} (known: {', '.join(KEYS[kind])})")
        if spec.get("direction", "rx") not in ("rx", "tx"):
            raise BadValue(f"{where}: topic {name}: direction must be 'rx' or 'tx'")
        specs[name] = {**DEFAULTS, **spec, "as": kind}
    return specs


def _bag_reader(src: Path) -> Any:
    from rosbags.rosbag2 import Reader

    folder = src.parent if src.name == "metadata.yaml" else src
    try:
        reader = Reader(folder)
        reader.open()
    except Exception as exc:   # rosbags raises its own kinds for a bad bag
        raise BadValue(f"{folder}: not a readable rosbag2 ({why(exc)})") from None
    return reader


def _typestore(reader: Any) -> Any:
    """The ROS 2 types rosbags ships, with every type the bag defines added."""
    from rosbags.interfaces import MessageDefinitionFormat
    from rosbags.typesys import Stores, get_typestore, get_types_from_idl, get_types_from_msg

    store = get_typestore(Stores.LATEST)
    for conn in reader.connections:
        if conn.msgtype in store.fielddefs:
            continue
        msgdef = conn.msgdef
        if msgdef is None or not msgdef.data:
            continue
        try:
            types = (get_types_from_idl(msgdef.data)
                     if msgdef.format == MessageDefinitionFormat.IDL
                     else get_types_from_msg(msgdef.data, conn.msgtype))
            store.register(types)
        except Exception:
            continue   # an unmapped topic's odd type: only a mapped one must decode
    return store


def import_bag(src: Path, maps: dict[str, Any], where: str, rec: Any) -> dict[str, Any]:
    """The mapped topics' messages into ``rec`` (host_tools/trace/import_logs.py ``Held``);
    returns what was read."""
    specs = _topic_specs(maps, where)
    reader = _bag_reader(src)
    try:
        have = {c.topic: c for c in reader.connections}
        missing = [t for t in specs if t not in have]
        if missing:
            raise BadValue(f"{src}: unknown topic {missing[0]}: the bag has "
                           f"{', '.join(sorted(have)) or 'no topics'}")
        store = _typestore(reader)
        for topic in specs:
            if have[topic].msgtype not in store.fielddefs:
                raise BadValue(f"{src}: topic {topic}'s type {have[topic].msgtype} is "
                               "neither a standard ROS 2 type nor defined in the bag")
        conns = [c for c in reader.connections if c.topic in specs]
        counts = _write(reader, conns, specs, store, rec, src)
    finally:
        reader.close()
    return {"messages": sum(counts.values()), "topics": counts}


def _write(reader: Any, conns: list, specs: dict[str, dict[str, Any]], store: Any,
           rec: Any, src: Path) -> dict[str, int]:
    counts = {t: 0 for t in specs}
    switches = {t: 0 for t in specs}
    t0 = None

    def joints(t_us: int, msg: Any, topic: str, spec: dict[str, Any]) -> None:
        names = [str(n) for n in _field(msg, spec["names"], topic)]
        pos = list(_field(msg, spec["positions"], topic))
        vel = list(_field(msg, spec["velocities"], topic)) or None
        eff = list(_field(msg, spec["efforts"], topic)) or None
        if len(pos) != len(names):
            raise BadValue(f"{topic}: a message has {len(names)} names and {len(pos)} "
                           f"positions at t={t_us / 1e6:.6f} s")
        rec.joints(t_us, names, pos, vel, eff)

    def switch(t_us: int, msg: Any, topic: str, spec: dict[str, Any]) -> None:
        value = _field(msg, spec["field"], topic)
        try:
            bits = sum(1 << i for i, v in enumerate(value) if v) if hasattr(value, "__len__") \
                else int(value)
        except (TypeError, ValueError):
            raise BadValue(f"{topic}: field {spec['field']!r} is neither an integer nor a "
                           "list of levels") from None
        bits &= (1 << LEGS) - 1
        changed = bits ^ switches[topic]
        for leg in range(LEGS):
            if changed & (1 << leg):
                rec.switch_edge(t_us, leg, bool(bits & (1 << leg)))
        switches[topic] = bits

    def frame(t_us: int, msg: Any, topic: str, spec: dict[str, Any]) -> None:
        arb = int(_field(msg, spec["id"], topic))
        data = bytes(bytearray(_field(msg, spec["data"], topic)))
        dlc = getattr(msg, "dlc", None)
        if isinstance(dlc, int) and 0 <= dlc <= len(data):
            data = data[:dlc]
        ext = bool(_field(msg, spec["extended"], topic)) if hasattr(msg, spec["extended"]) \
            else arb > 0x7FF
        rec.can(t_us, arb, data, spec.get("direction", "rx"), ext)

    handlers: dict[TopicAs, Callable[[int, Any, str, dict[str, Any]], None]] = {
        TopicAs.JOINTS: joints, TopicAs.SWITCHES: switch, TopicAs.CAN: frame}
    try:
        for conn, t_ns, raw in reader.messages(connections=conns):
            if t0 is None:
                t0 = t_ns
            topic = conn.topic
            spec = specs[topic]
            try:
                msg = store.deserialize_cdr(raw, conn.msgtype)
            except Exception as exc:
                raise BadValue(f"{src}: a {topic} message at t={(t_ns - t0) / 1e9:.6f} s does "
                               f"not decode as {conn.msgtype} ({why(exc)})") from None
            handlers[spec["as"]]((t_ns - t0) // 1000, msg, topic, spec)
            counts[topic] += 1
    except UserError:
        raise
    except Exception as exc:   # a storage file cut short
        raise BadValue(f"{src}: truncated or damaged bag ({why(exc)})") from None
    if not any(counts.values()):
        raise BadValue(f"{src}: the mapped topics hold no messages")
    return counts
