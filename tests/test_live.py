"""``hexhil run --live``: the trace's channels over the Foxglove WebSocket protocol on
127.0.0.1 while the run goes; a client that drops out mid-run does not stop it."""
from __future__ import annotations

import asyncio
import json
import struct
import subprocess
import time
from pathlib import Path

import pytest
import websockets
from conftest import HEXHIL, ROOT

WANTED = ("/scene", "/scene/frames", "/joints")
SUBPROTOCOL = "foxglove.sdk.v1"  # the SDK server speaks this; foxglove.websocket.v1 is refused


def _listening_on(port: int) -> list[str]:
    """Local addresses (hex, as /proc/net/tcp writes them) listening on ``port``."""
    out = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in Path(table).read_text().splitlines()[1:]:
            local, state = line.split()[1], line.split()[3]
            if state == "0A" and int(local.split(":")[1], 16) == port:
                out.append(local.split(":")[0])
    return out


async def _watch(url: str, seconds: float) -> dict[str, int]:
    """Subscribe to WANTED as they are advertised; count binary messages per topic."""
    counts: dict[str, int] = {}
    subs: dict[int, str] = {}
    async with websockets.connect(url, subprotocols=[SUBPROTOCOL]) as ws:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline and len(counts) < len(WANTED):
            try:
                msg = await asyncio.wait_for(ws.recv(), deadline - time.monotonic())
            except (asyncio.TimeoutError, websockets.ConnectionClosed):
                break
            if isinstance(msg, str):
                op = json.loads(msg)
                if op.get("op") == "advertise":
                    new = [{"id": c["id"], "channelId": c["id"]} for c in op["channels"]
                           if c["topic"] in WANTED]
                    subs.update({c["id"]: c["topic"] for c in op["channels"]
                                 if c["topic"] in WANTED})
                    if new:
                        await ws.send(json.dumps({"op": "subscribe", "subscriptions": new}))
            elif msg[0] == 1:  # message data: opcode, subscription id, timestamp, payload
                sub = struct.unpack_from("<I", msg, 1)[0]
                counts[subs[sub]] = counts.get(subs[sub], 0) + 1
    return counts


async def _drop_out(url: str) -> None:
    """A client that connects, subscribes to everything and vanishes without a goodbye."""
    ws = await websockets.connect(url, subprotocols=[SUBPROTOCOL])
    await asyncio.wait_for(ws.recv(), 5)
    ws.transport.abort()


def test_live_channels_reach_a_websocket_client():
    proc = subprocess.Popen([*HEXHIL, "run", "scenarios/obstacles-high-large.toml",
                             "--duration", "4", "--live", "0", "--realtime"], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        assert line.startswith("live: ws://127.0.0.1:"), line + proc.stderr.read()
        url = line.split()[1]
        port = int(url.rsplit(":", 1)[1])
        assert _listening_on(port) == ["0100007F"]  # 127.0.0.1 only
        asyncio.run(_drop_out(url))
        counts = asyncio.run(_watch(url, 3.5))   # stops once every channel has arrived
        assert set(counts) == set(WANTED), counts
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    assert "4.0 s simulated" in out


async def _advertised_at_connect(url: str) -> set[str]:
    """The topics of the advertisements that come with a connection, before any message."""
    topics: set[str] = set()
    async with websockets.connect(url, subprotocols=[SUBPROTOCOL]) as ws:
        while True:
            try:
                msg = await asyncio.wait_for(ws.recv(), 1.0)
            except asyncio.TimeoutError:
                return topics
            op = json.loads(msg)
            if op.get("op") == "advertise":
                topics |= {c["topic"] for c in op["channels"]}


def test_every_channel_is_advertised_before_a_client_can_subscribe():
    """foxglove-sdk enters a channel made while a client is connected in that client's
    table only after advertising it, so a prompt subscribe can be refused ("Unknown
    channel ID") and the panel stays empty: the live server makes every channel the
    recorder may open before it listens, and a client gets them all as it connects."""
    from hexhil.trace.live import LiveServer
    from hexhil.trace.topics import CHANNELS, T_CAN_PREFIX

    live = LiveServer(0)
    try:
        topics = asyncio.run(_advertised_at_connect(f"ws://127.0.0.1:{live.port}"))
    finally:
        live.close()
    assert set(CHANNELS) <= topics, set(CHANNELS) - topics
    assert T_CAN_PREFIX + "heartbeat" in topics
