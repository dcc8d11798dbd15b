"""The Foxglove bridge (issue 19): a WebSocket client sees the graph's topics and their messages.

In one process: a publisher node sends odometry, IMU, inertia, contact wrenches,
the latched gait phase, the scene's masses and the marker array; the bridge node serves
them on 127.0.0.1 (a free port); a ``websockets`` client speaking the Foxglove
WebSocket protocol sees the channels advertised (ROS 2 encoding: ``cdr`` with the
``ros2msg`` schema), subscribes and receives the messages that were published (CDR, unchanged),
plus the derived scene arrows.

foxglove-sdk 0.30 names the protocol ``foxglove.sdk.v1`` (``foxglove.websocket.v1``
under its new name, which the server no longer accepts on its own); the client
offers both, as Foxglove apps do.
"""

from __future__ import annotations

import asyncio
import json
import struct
import threading
from collections.abc import Iterator

import numpy as np
import pytest
import websockets
from nav_msgs.msg import Odometry
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import String
from visualization_msgs.msg import Marker, MarkerArray

from splitter_bringup.nodes.foxglove_bridge_node import SCENE_TOPIC, TF_TOPIC, FoxgloveBridgeNode
from splitter_msgs_py import names
from splitter_msgs_py.conversions import (
    TOPIC_MESSAGE_CLASSES,
    imu_to_msg,
    odom_to_msg,
    vector3_to_msg,
    wrench_to_msg,
)
from splitter_msgs_py.qos import qos_for
from splitter_sim.core.scene import scene_from_pose
from splitter_sim.messages import masses_to_msg, scene_markers

SUBPROTOCOLS = ["foxglove.websocket.v1", "foxglove.sdk.v1"]
PUBLISH_PERIOD_S = 0.02  # [s] wall
TIMEOUT_S = 20.0  # [s] wall, whole client exchange
MESSAGE_DATA_OP = 0x01  # binary opcode of a message in the Foxglove WebSocket protocol


class FakeSimulator(Node):
    """Publishes a moving state, the scene's masses and the markers on the graph's topics."""

    def __init__(self, context) -> None:
        super().__init__("fake_simulator", context=context)
        self.pubs = {
            t: self.create_publisher(TOPIC_MESSAGE_CLASSES[t], t, qos_for(t))
            for t in (
                names.ODOM,
                names.IMU,
                names.INERTIA,
                names.MARKERS,
                names.SCENE_MASSES,
                names.GAIT_PHASE,
                *names.CONTACT_WRENCHES,
            )
        }
        self.pubs[names.GAIT_PHASE].publish(String(data="IN_FLIGHT"))
        self.t_ns = 0
        self.sent_odom: dict[int, bytes] = {}
        self.create_timer(PUBLISH_PERIOD_S, self._tick)

    def _tick(self) -> None:
        self.t_ns += 5_000_000
        t = self.t_ns
        x = 1e-9 * t
        odom = odom_to_msg(t, [x, 0.0, 1.0], [1.0, 0.0, 0.0, 0.0], [1.0, 0, 0], [0, 1.0, 0])
        self.sent_odom[t] = serialize_message(odom)
        self.pubs[names.ODOM].publish(odom)
        self.pubs[names.IMU].publish(imu_to_msg(t, [1.0, 0, 0, 0], [0, 1.0, 0], [0, 0, 0]))
        self.pubs[names.INERTIA].publish(vector3_to_msg(t, [1.0, 140.0, 140.0]))
        for i, topic in enumerate(names.CONTACT_WRENCHES):
            self.pubs[topic].publish(wrench_to_msg(t, [0.0, 0.0, 10.0 * i]))
        masses = np.zeros((10, 3))
        masses[:, 0] = [x + (2.8 if i < 5 else -2.8) for i in range(10)]
        masses[:, 2] = [1.0 - 0.1 * (i % 5) for i in range(10)]
        scene = scene_from_pose(
            t,
            [x, 0.0, 1.0],
            [1.0, 0.0, 0.0, 0.0],
            mass_positions_world=masses,
            principal_inertia_kg_m2=[1.0, 140.0, 140.0],
            angular_velocity_rad_s=[0.0, 1.0, 0.0],
        )
        self.pubs[names.SCENE_MASSES].publish(masses_to_msg(scene))
        self.pubs[names.MARKERS].publish(scene_markers(scene))


@pytest.fixture
def bridge_graph(ros_context) -> Iterator[tuple[FoxgloveBridgeNode, FakeSimulator]]:
    bridge = FoxgloveBridgeNode(
        context=ros_context,
        parameter_overrides=[Parameter("port", value=0), Parameter("latched_period_s", value=0.2)],
    )
    sim = FakeSimulator(ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(bridge)
    executor.add_node(sim)
    stop = threading.Event()

    def spin() -> None:
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.05)

    thread = threading.Thread(target=spin, daemon=True)
    thread.start()
    try:
        yield bridge, sim
    finally:
        stop.set()
        thread.join(timeout=5.0)
        executor.shutdown()
        bridge.destroy_node()
        sim.destroy_node()


async def _exchange(port: int, topics: list[str], wanted: int) -> dict:
    """Connect, collect advertised channels, subscribe to ``topics``, receive messages."""
    uri = f"ws://127.0.0.1:{port}"
    async with websockets.connect(uri, subprotocols=SUBPROTOCOLS, proxy=None) as ws:
        channels: dict[str, dict] = {}
        server_info = None
        while not all(t in channels for t in topics):
            msg = await ws.recv()
            if isinstance(msg, bytes):
                continue
            data = json.loads(msg)
            if data["op"] == "serverInfo":
                server_info = data
            elif data["op"] == "advertise":
                channels.update({c["topic"]: c for c in data["channels"]})
        subscriptions = {sub_id: topic for sub_id, topic in enumerate(topics, start=1)}
        await ws.send(
            json.dumps(
                {
                    "op": "subscribe",
                    "subscriptions": [
                        {"id": sub_id, "channelId": channels[topic]["id"]}
                        for sub_id, topic in subscriptions.items()
                    ],
                }
            )
        )
        received: dict[str, list[tuple[int, bytes]]] = {t: [] for t in topics}
        while min(len(v) for v in received.values()) < wanted:
            msg = await ws.recv()
            if isinstance(msg, bytes) and msg[0] == MESSAGE_DATA_OP:
                sub_id, log_time = struct.unpack_from("<IQ", msg, 1)
                received[subscriptions[sub_id]].append((log_time, msg[13:]))
        return {
            "subprotocol": ws.subprotocol,
            "server_info": server_info,
            "channels": channels,
            "received": received,
        }


def test_client_sees_channels_and_receives_messages(bridge_graph) -> None:
    bridge, sim = bridge_graph
    topics = [names.ODOM, names.MARKERS, SCENE_TOPIC, names.GAIT_PHASE, TF_TOPIC]
    result = asyncio.run(asyncio.wait_for(_exchange(bridge.port, topics, 3), TIMEOUT_S))
    assert result["subprotocol"] in SUBPROTOCOLS
    channels = result["channels"]
    for topic in (names.ODOM, names.MARKERS, names.IMU, names.INERTIA, *names.CONTACT_WRENCHES):
        assert channels[topic]["encoding"] == "cdr"
        assert channels[topic]["schemaEncoding"] == "ros2msg"
        assert channels[topic]["schemaName"] == names.TOPIC_TYPES[topic]
    assert "MSG: geometry_msgs/PoseWithCovariance" in channels[names.ODOM]["schema"]
    received = result["received"]
    # odometry: the message published, logged at its header stamp. The CDR bytes are
    # compared as messages: the DDS writer leaves its alignment padding (after the
    # frame id strings) uninitialised, so raw bytes differ from rclpy's serialisation.
    for log_time, payload in received[names.ODOM]:
        assert len(payload) == len(sim.sent_odom[log_time])
        sent = deserialize_message(sim.sent_odom[log_time], Odometry)
        assert deserialize_message(payload, Odometry) == sent
    markers = deserialize_message(received[names.MARKERS][0][1], MarkerArray)
    assert sorted(m.id for m in markers.markers if m.ns == "splitter_masses") == list(range(10))
    # scene: axes, angular momentum and hemi b's contact force (hemi a's is zero: deleted)
    scene = deserialize_message(received[SCENE_TOPIC][-1][1], MarkerArray)
    added = {m.id for m in scene.markers if m.action == Marker.ADD}
    deleted = {m.id for m in scene.markers if m.action == Marker.DELETE}
    assert added == {0, 1, 2, 3, 5} and deleted == {4}
    # latched gait phase reaches a late client (re-sent every latched_period_s)
    assert deserialize_message(received[names.GAIT_PHASE][0][1], String).data == "IN_FLIGHT"


def test_busy_port_is_an_invalid_parameter(ros_context) -> None:
    from splitter_msgs_py.parameters import InvalidParameterError

    first = FoxgloveBridgeNode(
        context=ros_context, parameter_overrides=[Parameter("port", value=0)]
    )
    try:
        with pytest.raises(InvalidParameterError, match="cannot serve"):
            FoxgloveBridgeNode(
                context=ros_context, parameter_overrides=[Parameter("port", value=first.port)]
            )
    finally:
        first.destroy_node()
