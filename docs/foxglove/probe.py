"""Probe a running Foxglove bridge: advertised channels and messages received per topic.

    .venv/bin/splitter launch spin_stabilization --real-time --no-record --foxglove 8765 &
    .venv/bin/python docs/foxglove/probe.py --port 8765 --topics /splitter/odom /splitter/markers

Retries the connection until the server is up (``--wait``), subscribes to the
topics once advertised, counts messages for ``--listen`` seconds from the first one and prints one
line per topic. Exit code 0 when every topic was advertised and received.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import struct
import sys
import time

import websockets

SUBPROTOCOLS = ["foxglove.websocket.v1", "foxglove.sdk.v1"]
MESSAGE_DATA_OP = 0x01


async def probe(host: str, port: int, topics: list[str], wait_s: float, listen_s: float) -> int:
    deadline = time.monotonic() + wait_s
    while True:
        try:
            ws = await websockets.connect(
                f"ws://{host}:{port}", subprotocols=SUBPROTOCOLS, proxy=None
            )
            break
        except (OSError, websockets.InvalidHandshake):
            if time.monotonic() > deadline:
                print(f"no server on {host}:{port} within {wait_s} s")
                return 1
            await asyncio.sleep(0.5)
    async with ws:
        print(f"connected to ws://{host}:{port}, subprotocol {ws.subprotocol}")
        channels: dict[str, dict] = {}
        while not all(t in channels for t in topics):
            msg = await asyncio.wait_for(ws.recv(), wait_s)
            if isinstance(msg, str):
                data = json.loads(msg)
                if data["op"] == "advertise":
                    channels.update({c["topic"]: c for c in data["channels"]})
        print(f"advertised: {len(channels)} channels: {', '.join(sorted(channels))}")
        subs = {i: t for i, t in enumerate(topics, start=1)}
        await ws.send(
            json.dumps(
                {
                    "op": "subscribe",
                    "subscriptions": [
                        {"id": i, "channelId": channels[t]["id"]} for i, t in subs.items()
                    ],
                }
            )
        )
        counts = dict.fromkeys(topics, 0)
        first: dict[str, float] = {}
        last: dict[str, float] = {}
        end = time.monotonic() + wait_s  # until the first message, then listen_s more
        while time.monotonic() < end:
            try:
                msg = await asyncio.wait_for(ws.recv(), max(0.01, end - time.monotonic()))
            except TimeoutError:
                break
            if isinstance(msg, bytes) and msg[0] == MESSAGE_DATA_OP:
                sub_id, log_time = struct.unpack_from("<IQ", msg, 1)
                topic = subs[sub_id]
                if not first:
                    end = time.monotonic() + listen_s
                counts[topic] += 1
                first.setdefault(topic, log_time * 1e-9)
                last[topic] = log_time * 1e-9
        for t in topics:
            c = channels[t]
            span = f"stamps {first[t]:.3f}..{last[t]:.3f} s" if t in first else "no stamps"
            print(
                f"{t}: {c['schemaName']} ({c['encoding']}/{c['schemaEncoding']}), "
                f"{counts[t]} messages in {listen_s:.1f} s wall after the first, {span}"
            )
        return 0 if all(counts.values()) else 1


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--port", type=int, default=8765)
    parser.add_argument("--topics", nargs="+", default=["/splitter/odom", "/splitter/markers"])
    parser.add_argument("--wait", type=float, default=120.0, help="[s] for the server")
    parser.add_argument("--listen", type=float, default=3.0, help="[s] of messages counted")
    args = parser.parse_args()
    return asyncio.run(probe(args.host, args.port, args.topics, args.wait, args.listen))


if __name__ == "__main__":
    sys.exit(main())
