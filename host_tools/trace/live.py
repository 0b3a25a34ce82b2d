"""A run's trace served live over the Foxglove WebSocket protocol (``hexhil run --live``).

The recorder hands every channel it opens and every chunk it writes to ``LiveServer``,
which republishes them through ``foxglove-sdk``'s server (Rust core, the protocol Foxglove
itself speaks) on 127.0.0.1: a viewer sees the channels of the MCAP file, message for
message, each window (0.1 s of virtual time with ``--live``) as it is written. The SDK keeps
its own context, so nothing else in the process logs to this server.

Every channel a recorder may open is made before the server listens. The SDK sends a new
channel's advertisement to the connected clients before it enters the channel in each
client's table (foxglove-sdk 0.30 ``ConnectedClient::advertise_channels``): a client that
subscribes at once to a channel made mid-run, while the thread making it is preempted, is
told "Unknown channel ID" and never gets its messages (a Foxglove panel stays empty). The
channels that exist when a client connects are entered before its first message is read.
"""
from __future__ import annotations

from typing import Any, Iterable

import foxglove

from hexhil.trace.channels import every_channel
from hexhil.protocol.errors import BadFile

# Messages held per client (the SDK's default, set here so the bound is ours): a client
# that stops reading loses the oldest data messages, never the run's memory; one whose
# control queue of the same size fills is disconnected. Several clients are served.
BACKLOG = 1024


class LiveServer:
    """The Foxglove WebSocket server of one run (127.0.0.1 only)."""

    flush_interval_us = 100_000  # the recorder's window: a viewer sees 0.1 s steps

    def __init__(self, port: int,
                 channels: Iterable[tuple[str, str, str, bytes, str]] | None = None) -> None:
        """``channels``: (topic, schema name, schema encoding, schema data, message
        encoding) made before the server listens; by default every channel a recorder may
        open (host_tools/trace/channels.py ``every_channel``)."""
        self._context = foxglove.Context()
        self._by_topic = {spec[0]: self._new_channel(*spec)
                          for spec in (every_channel() if channels is None else channels)}
        try:
            self._server = foxglove.start_server(name="hexhil", host="127.0.0.1", port=port,
                                                 context=self._context,
                                                 message_backlog_size=BACKLOG)
        except Exception as exc:  # the SDK raises its own error type for a bind failure
            raise BadFile(f"live_port: cannot listen on 127.0.0.1:{port}: {exc}",
                          params=("live_port",)) from None
        self.port = self._server.port
        self._channels: dict[int, foxglove.Channel] = {}

    def _new_channel(self, topic: str, schema_name: str, schema_encoding: str,
                     schema_data: bytes, message_encoding: str) -> foxglove.Channel:
        schema = foxglove.Schema(name=schema_name, encoding=schema_encoding, data=schema_data)
        return foxglove.Channel(topic, schema=schema, message_encoding=message_encoding,
                                context=self._context)

    def channel(self, cid: int, topic: str, schema_name: str, schema_encoding: str,
                schema_data: bytes, message_encoding: str) -> None:
        """The recorder's channel ``cid``: the one made for ``topic`` before the server
        listened, else a new one (advertised now)."""
        made = self._by_topic.get(topic)
        if made is None:
            made = self._by_topic[topic] = self._new_channel(
                topic, schema_name, schema_encoding, schema_data, message_encoding)
        self._channels[cid] = made

    def log(self, messages: list[tuple[int, int, Any]]) -> None:
        """Publish (log_time_ns, channel id, data) messages, in the order given."""
        channels = self._channels
        for t, cid, data in messages:
            channels[cid].log(bytes(data), log_time=t)

    def close(self) -> None:
        self._server.stop()
