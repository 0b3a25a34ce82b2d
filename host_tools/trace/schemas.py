"""The schema data of the trace's channels: the fixed topics' (``topics.CHANNELS``) and
the DBC-decoded CAN frames', for the recorder and for the live server, which makes every
channel a recorder may open before a viewer connects (host_tools/trace/live.py)."""
from __future__ import annotations

import functools
import json
from pathlib import Path
from typing import Any

from host_tools.trace import protobuf as pb
from host_tools.trace.topics import (CAN_SCHEMA_PREFIX, CHANNELS, T_CAN_PREFIX,
                                     schema_encoding)
from protocol import dynamixel


@functools.cache
def dbc():
    """The project's DBC through cantools (loaded once a process: ~13 ms, as much as
    recording 10 s of a run), or None while protocol/hexhil.dbc is absent."""
    path = Path(dynamixel.__file__).with_name("hexhil.dbc")
    if not path.exists():
        return None
    import cantools

    return cantools.database.load_file(str(path))


@functools.cache
def can_json_schema(msg: Any) -> str:
    """The JSON schema of one DBC frame's decoded signals, units in the descriptions."""
    props = {s.name: {"type": "number", "description": f"{s.comment or s.name} [{s.unit or '-'}]"}
             for s in msg.signals}
    props["direction"] = {"type": "string"}
    return json.dumps({"title": CAN_SCHEMA_PREFIX + msg.name, "type": "object",
                       "properties": props}, sort_keys=True)


def topic_schema(topic: str) -> bytes:
    """The schema data of one of the fixed topics (``topics.CHANNELS``)."""
    schema_name, encoding = CHANNELS[topic]
    if encoding == "protobuf":
        return pb.descriptor_set(schema_name)
    return json.dumps({"title": schema_name, "type": "object"}, sort_keys=True).encode()


def every_channel() -> list[tuple[str, str, str, bytes, str]]:
    """(topic, schema name, schema encoding, schema data, message encoding) of every
    channel a recorder may open: the fixed topics and one per DBC frame."""
    out = [(topic, name, schema_encoding(enc), topic_schema(topic), enc)
           for topic, (name, enc) in CHANNELS.items()]
    db = dbc()
    for msg in db.messages if db is not None else ():
        out.append((T_CAN_PREFIX + msg.name, CAN_SCHEMA_PREFIX + msg.name, "jsonschema",
                    can_json_schema(msg).encode(), "json"))
    return out
