"""The trace's channels: each topic's schema and channel records, written on the topic's
first message (and announced to the live server, host_tools/trace/live.py)."""
from __future__ import annotations

import json
from typing import Any, Callable

from hexhil.trace import protobuf as pb
from hexhil.trace.can_signals import dbc, json_schema
from hexhil.trace.topics import CAN_SCHEMA_PREFIX, CHANNELS, T_CAN_PREFIX, schema_encoding
from hexhil.trace.writer import TraceWriter


class Channels:
    """Topic -> channel id (``ids``), schemas shared by name."""

    def __init__(self, writer: TraceWriter, live: Any = None,
                 write_failed: Callable[[OSError], None] | None = None) -> None:
        self._writer = writer
        self._live = live
        self._write_failed = write_failed   # a full disk: the recorder's one line
        self.ids: dict[str, int] = {}
        self._schemas: dict[str, int] = {}
        self._schema_data: dict[str, bytes] = {}  # for the live server's channels

    def add(self, topic: str, schema_name: str, encoding: str,
            schema_data: Callable[[], bytes]) -> int:
        """The channel id of ``topic``, writing its schema (first use) and channel."""
        sid = self._schemas.get(schema_name)
        cid = len(self.ids) + 1
        try:
            if sid is None:
                sid = self._schemas[schema_name] = len(self._schemas) + 1
                data = self._schema_data[schema_name] = schema_data()
                self._writer.schema(sid, schema_name, schema_encoding(encoding), data)
            self._writer.channel(cid, topic, encoding, sid)
        except OSError as exc:
            if self._write_failed is None:
                raise
            self._write_failed(exc)
        self.ids[topic] = cid
        if self._live is not None:
            self._live.channel(cid, topic, schema_name, schema_encoding(encoding),
                               self._schema_data[schema_name], encoding)
        return cid

    def of(self, topic: str) -> int:
        """The channel id of one of the fixed topics (``topics.CHANNELS``)."""
        cid = self.ids.get(topic)
        if cid is not None:
            return cid
        schema_name, encoding = CHANNELS[topic]
        return self.add(topic, schema_name, encoding, lambda: topic_schema(topic))


def topic_schema(topic: str) -> bytes:
    """The schema data of one of the fixed topics (``topics.CHANNELS``)."""
    schema_name, encoding = CHANNELS[topic]
    if encoding == "protobuf":
        return pb.descriptor_set(schema_name)
    return json.dumps({"title": schema_name, "type": "object"}, sort_keys=True).encode()


def every_channel() -> list[tuple[str, str, str, bytes, str]]:
    """(topic, schema name, schema encoding, schema data, message encoding) of every
    channel a recorder may open: the fixed topics and one per DBC frame (the live server
    makes them all before a viewer connects, host_tools/trace/live.py)."""
    out = [(topic, name, schema_encoding(enc), topic_schema(topic), enc)
           for topic, (name, enc) in CHANNELS.items()]
    db = dbc()
    for msg in db.messages if db is not None else ():
        out.append((T_CAN_PREFIX + msg.name, CAN_SCHEMA_PREFIX + msg.name, "jsonschema",
                    json_schema(msg).encode(), "json"))
    return out
