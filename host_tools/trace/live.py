"""A run's trace served live over the Foxglove WebSocket protocol (``hexhil run --live``).

The recorder hands every channel it opens and every chunk it writes to ``LiveServer``,
which republishes them through ``foxglove-sdk``'s server (Rust core, the protocol Foxglove
itself speaks) on 127.0.0.1: a viewer sees the channels of the MCAP file, message for
message, each window (0.1 s of virtual time with ``--live``) as it is written. The SDK keeps
its own context, so nothing else in the process logs to this server.
"""
from __future__ import annotations

from typing import Any

import foxglove

from protocol.errors import UserError

# Messages held per client (the SDK's default, set here so the bound is ours): a client
# that stops reading loses the oldest data messages, never the run's memory; one whose
# control queue of the same size fills is disconnected. Several clients are served.
BACKLOG = 1024


class LiveServer:
    """The Foxglove WebSocket server of one run (127.0.0.1 only)."""

    flush_interval_us = 100_000  # the recorder's window: a viewer sees 0.1 s steps

    def __init__(self, port: int) -> None:
        self._context = foxglove.Context()
        try:
            self._server = foxglove.start_server(name="hexhil", host="127.0.0.1", port=port,
                                                 context=self._context,
                                                 message_backlog_size=BACKLOG)
        except Exception as exc:  # the SDK raises its own error type for a bind failure
            raise UserError(f"live_port: cannot listen on 127.0.0.1:{port}: {exc}",
                            params=("live_port",)) from None
        self.port = self._server.port
        self._channels: dict[int, foxglove.Channel] = {}

    def channel(self, cid: int, topic: str, schema_name: str, schema_encoding: str,
                schema_data: bytes, message_encoding: str) -> None:
        """Advertise the recorder's channel ``cid``."""
        schema = foxglove.Schema(name=schema_name, encoding=schema_encoding, data=schema_data)
        self._channels[cid] = foxglove.Channel(topic, schema=schema,
                                               message_encoding=message_encoding,
                                               context=self._context)

    def log(self, messages: list[tuple[int, int, Any]]) -> None:
        """Publish (log_time_ns, channel id, data) messages, in the order given."""
        channels = self._channels
        for t, cid, data in messages:
            channels[cid].log(bytes(data), log_time=t)

    def close(self) -> None:
        self._server.stop()
