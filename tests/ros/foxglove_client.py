"""A minimal Foxglove WebSocket client (the ws-protocol, ``foxglove.sdk.v1``) for the live-view
tests: connect, subscribe to channels by topic, collect the messages until the server goes."""

from __future__ import annotations

import asyncio
import json
import struct
import time
from dataclasses import dataclass, field

SUBPROTOCOL = "foxglove.sdk.v1"  # the SDK's name for the ws-protocol (formerly foxglove.websocket.v1)


@dataclass
class Received:
    channels: dict[str, dict] = field(default_factory=dict)  # topic -> advertised channel
    messages: dict[str, list[bytes]] = field(default_factory=dict)  # topic -> payloads
    server_info: dict | None = None


async def _collect(url: str, topics: tuple[str, ...], until: float, out: Received) -> None:
    import websockets

    async with websockets.connect(url, subprotocols=[SUBPROTOCOL], max_size=None) as ws:
        by_sub: dict[int, str] = {}
        while time.monotonic() < until:
            try:
                raw = await asyncio.wait_for(ws.recv(), timeout=max(0.1, until - time.monotonic()))
            except (TimeoutError, websockets.ConnectionClosed):
                return
            if isinstance(raw, str):
                msg = json.loads(raw)
                if msg.get("op") == "serverInfo":
                    out.server_info = msg
                elif msg.get("op") == "advertise":
                    subs = []
                    for ch in msg["channels"]:
                        out.channels[ch["topic"]] = ch
                        if ch["topic"] in topics:
                            sid = len(by_sub) + 1
                            by_sub[sid] = ch["topic"]
                            subs.append({"id": sid, "channelId": ch["id"]})
                    if subs:
                        await ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
            elif raw and raw[0] == 0x01:  # message data: op, subscription id, timestamp, payload
                sid, _stamp = struct.unpack_from("<IQ", raw, 1)
                out.messages.setdefault(by_sub[sid], []).append(bytes(raw[13:]))


def connect_when_up(port: int, timeout: float = 60.0) -> None:
    """Wait until something listens on the port (the watch node starts before the world)."""
    import socket

    end = time.monotonic() + timeout
    while time.monotonic() < end:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.05)
    raise TimeoutError(f"nothing listens on port {port} after {timeout} s")


def collect(port: int, topics: tuple[str, ...], seconds: float) -> Received:
    """Subscribe to ``topics`` and collect for up to ``seconds`` (or until the server closes)."""
    out = Received()
    asyncio.run(_collect(f"ws://127.0.0.1:{port}", topics, time.monotonic() + seconds, out))
    return out
