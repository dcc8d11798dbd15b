"""``foxglove_bridge`` node: serves the running graph to Foxglove over its WebSocket protocol.

Thin ROS layer over the ``foxglove-sdk`` package: one Foxglove channel per graph
topic, in the ROS 2 message encoding (``cdr`` payloads exactly as received with
``raw=True`` subscriptions, the ``ros2msg`` schema text rosbag2 writes, from
:func:`splitter_bag.core.definitions.message_definition`), so Foxglove decodes
them as it decodes a bag. Two derived channels complete the 3D scene, drawn from
the typed scene (:class:`splitter_sim.core.scene.Scene`: the masses of
``/splitter/scene/masses`` with the latest odometry, IMU rate, inertia and contact
wrenches) each time ``/splitter/scene/masses`` arrives:

* ``/splitter/scene`` (``visualization_msgs/msg/MarkerArray``, cdr): body axes,
  the world angular momentum and the contact force of each hemi as arrows;
* ``/splitter/tf`` (``foxglove.FrameTransforms``): ``world`` -> ``base`` from odometry;
* ``/splitter/ground`` (``foxglove.SceneUpdate``), unless the ground is level: the
  terrain of the parameters ``ground_slope_deg``, ``ground_slope_azimuth_deg`` and
  ``ground_steps_m`` (the simulator's, :class:`splitter_model.terrain.Terrain`) as
  cubes, the base plane as a thin slab about the robot tilted with the slope and a
  box per step (:func:`splitter_sim.core.scene.ground_boxes`; entity ids
  ``ground_base_plane`` and ``ground_step_<i>``, the same in every update).

Message times are the messages' header stamps (simulated time); headerless
messages take the latest stamp seen. Latched topics (gait phase, references) are
sent again every ``latched_period_s`` (wall) so that a client connecting later
sees them. The server binds ``host:port`` (127.0.0.1 unless told otherwise;
port 0 picks a free one, read back from :attr:`FoxgloveBridgeNode.port`).

Protocol note: foxglove-sdk 0.30 negotiates the WebSocket subprotocol
``foxglove.sdk.v1`` (the ``foxglove.websocket.v1`` protocol under its new name);
a client must offer it (current Foxglove apps do).
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import foxglove
import numpy as np
from foxglove.channels import FrameTransformsChannel, SceneUpdateChannel
from foxglove.messages import (
    Color,
    CubePrimitive,
    FrameTransform,
    FrameTransforms,
    Pose,
    Quaternion,
    SceneEntity,
    SceneUpdate,
    Timestamp,
    Vector3,
)
from foxglove.websocket import Capability
from geometry_msgs.msg import Point
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.serialization import deserialize_message, serialize_message
from visualization_msgs.msg import Marker, MarkerArray

from splitter_bag.core.definitions import header_stamp_ns, message_definition, starts_with_header
from splitter_model.terrain import Terrain
from splitter_msgs_py import names
from splitter_msgs_py.conversions import TOPIC_MESSAGE_CLASSES
from splitter_msgs_py.core.parameter_fields import parameter_fields
from splitter_msgs_py.node_pattern import run_node
from splitter_msgs_py.parameters import InvalidParameterError, ParameterSpec, declare_parameters
from splitter_msgs_py.qos import LATCHED_QOS, qos_for
from splitter_sim.core.scene import Arrow, Box, Ground, ground_boxes, scene_from_pose
from splitter_sim.core.simulator import SimConfig
from splitter_sim.messages import masses_from_msg

NODE_NAME = "foxglove_bridge"
DEFAULT_PORT = 8765
DEFAULT_HOST = "127.0.0.1"
SCENE_TOPIC = "/splitter/scene"
TF_TOPIC = "/splitter/tf"
GROUND_TOPIC = "/splitter/ground"
GROUND_ENTITY_PREFIX = "ground_"  # entity id: the prefix and the box's name
# the terrain's parameters, as the simulator declares them (names, ranges, descriptions)
GROUND_PARAMETERS = ("ground_slope_deg", "ground_slope_azimuth_deg", "ground_steps_m")
SCENE_NS = "splitter_scene"
# marker id of each scene arrow (a missing contact arrow is deleted by id)
ARROW_IDS = {
    "axis_x": 0,
    "axis_y": 1,
    "axis_z": 2,
    "angular_momentum": 3,
    "contact_a": 4,
    "contact_b": 5,
}
ARROW_SHAFT_M = 0.03  # [m] arrow shaft diameter
ARROW_HEAD_M = 0.08  # [m] arrow head diameter
ARROW_HEAD_LENGTH_M = 0.12  # [m]
# every graph topic but /clock (a message per simulation step, nothing to look at)
DEFAULT_TOPICS = tuple(t for t in names.TOPIC_TYPES if t != names.CLOCK)

PARAMETERS = (
    ParameterSpec("host", DEFAULT_HOST, "address the WebSocket server binds"),
    ParameterSpec("port", DEFAULT_PORT, "WebSocket port (0: a free one)", 0, 65535),
    ParameterSpec(
        "topics",
        list(DEFAULT_TOPICS),
        "graph topics served (each of splitter_msgs_py.names.TOPIC_TYPES)",
        item_type=str,
        choices=tuple(names.TOPIC_TYPES),
    ),
    ParameterSpec("scene", True, "serve /splitter/scene arrows and /splitter/tf"),
    ParameterSpec(
        "latched_period_s", 1.0, "wall period of re-sending latched topics [s]", 0.05, 3600.0
    ),
    *(spec for name, _default, spec in parameter_fields(SimConfig) if name in GROUND_PARAMETERS),
)


def _point(p: Sequence[float]) -> Point:
    return Point(x=float(p[0]), y=float(p[1]), z=float(p[2]))


def arrow_markers(arrows: Sequence[Arrow], stamp: object) -> MarkerArray:
    """The scene arrows as ``Marker.ARROW`` (world frame); absent ones deleted by id."""
    out = MarkerArray()
    present = {a.name: a for a in arrows}
    for name, marker_id in ARROW_IDS.items():
        m = Marker()
        m.header.stamp = stamp
        m.header.frame_id = names.WORLD_FRAME
        m.ns = SCENE_NS
        m.id = marker_id
        arrow = present.get(name)
        if arrow is None:
            m.action = Marker.DELETE
            out.markers.append(m)
            continue
        m.type = Marker.ARROW
        m.action = Marker.ADD
        m.pose.orientation.w = 1.0
        m.points = [_point(arrow.start), _point(arrow.end)]
        m.scale.x, m.scale.y, m.scale.z = ARROW_SHAFT_M, ARROW_HEAD_M, ARROW_HEAD_LENGTH_M
        m.color.r, m.color.g, m.color.b, m.color.a = arrow.color
        out.markers.append(m)
    return out


def ground_scene_update(boxes: Sequence[Box], t_ns: int) -> SceneUpdate:
    """The ground's boxes as one ``foxglove.SceneUpdate``: an entity per box holding its
    cube (world frame, id ``ground_<box name>``, no lifetime: the next update replaces it)."""
    timestamp = Timestamp(sec=int(t_ns // 1_000_000_000), nsec=int(t_ns % 1_000_000_000))
    entities = []
    for box in boxes:
        w, x, y, z = (float(v) for v in box.orientation_wxyz)
        cx, cy, cz = (float(v) for v in box.centre_m)
        sx, sy, sz = (float(v) for v in box.size_m)
        r, g, b, a = (float(v) for v in box.color)
        cube = CubePrimitive(
            pose=Pose(
                position=Vector3(x=cx, y=cy, z=cz),
                orientation=Quaternion(x=x, y=y, z=z, w=w),
            ),
            size=Vector3(x=sx, y=sy, z=sz),
            color=Color(r=r, g=g, b=b, a=a),
        )
        entities.append(
            SceneEntity(
                timestamp=timestamp,
                frame_id=names.WORLD_FRAME,
                id=f"{GROUND_ENTITY_PREFIX}{box.name}",
                cubes=[cube],
            )
        )
    return SceneUpdate(entities=entities)


def ground_of_parameters(values: dict) -> Ground:
    """The ground of the node's ``ground_*`` parameters; InvalidParameterError if invalid."""
    try:
        terrain = Terrain.from_parameters(
            values["ground_slope_deg"],
            values["ground_slope_azimuth_deg"],
            values["ground_steps_m"],
        )
    except ValueError as exc:
        raise InvalidParameterError(f"ground parameters: {exc}") from exc
    return Ground(terrain=terrain)


class FoxgloveBridgeNode(Node):
    """Forwards the graph's topics to a Foxglove WebSocket server and adds the scene arrows."""

    def __init__(self, **kwargs) -> None:
        super().__init__(NODE_NAME, **kwargs)
        values = declare_parameters(self, PARAMETERS)
        self._ground = ground_of_parameters(values)
        self._fg_context = foxglove.Context()
        self._fg_channels: dict[str, foxglove.Channel] = {}
        self._has_header: dict[str, bool] = {}
        self._last: dict[str, bytes] = {}
        self._latched = [
            t for t in values["topics"] if qos_for(t).durability == LATCHED_QOS.durability
        ]
        self._latest_ns: int | None = None
        self.scene_count = 0
        for topic in values["topics"]:
            self._add_topic(topic)
        self._scene = bool(values["scene"])
        self._scene_channel: foxglove.Channel | None = None
        self._tf_channel: FrameTransformsChannel | None = None
        self._ground_channel: SceneUpdateChannel | None = None
        if self._scene:
            self._scene_channel = self._ros_channel(SCENE_TOPIC, names.TOPIC_TYPES[names.MARKERS])
            self._tf_channel = FrameTransformsChannel(TF_TOPIC, context=self._fg_context)
            if not self._ground.level:
                self._ground_channel = SceneUpdateChannel(GROUND_TOPIC, context=self._fg_context)
        try:
            self._server = foxglove.start_server(
                name="splitter",
                host=str(values["host"]),
                port=int(values["port"]),
                capabilities=[Capability.Time],
                supported_encodings=["cdr"],
                context=self._fg_context,
            )
        except RuntimeError as exc:  # foxglove.FoxgloveError: port in use, bad address
            self.destroy_node()
            raise InvalidParameterError(
                f"cannot serve on {values['host']}:{values['port']}: {exc}"
            ) from exc
        self.host = str(values["host"])
        self.port = int(self._server.port)
        if self._latched:
            self.create_timer(
                float(values["latched_period_s"]),
                self._resend_latched,
                clock=Clock(clock_type=ClockType.STEADY_TIME),
            )
        self.get_logger().info(
            f"Foxglove WebSocket server on ws://{self.host}:{self.port} "
            f"({len(self._fg_channels)} topics{', scene' if self._scene else ''}"
            f"{', ground' if self._ground_channel is not None else ''})"
        )

    def _ros_channel(self, topic: str, type_name: str) -> foxglove.Channel:
        definition = message_definition(type_name)
        schema = foxglove.Schema(
            name=type_name,
            encoding=definition.encoding,
            data=definition.encoded_message_definition.encode("utf-8"),
        )
        return foxglove.Channel(
            topic, schema=schema, message_encoding="cdr", context=self._fg_context
        )

    def _add_topic(self, topic: str) -> None:
        type_name = names.TOPIC_TYPES[topic]
        self._fg_channels[topic] = self._ros_channel(topic, type_name)
        self._has_header[topic] = starts_with_header(type_name)
        self.create_subscription(
            TOPIC_MESSAGE_CLASSES[topic],
            topic,
            lambda data, topic=topic: self._on_message(topic, data),
            qos_for(topic),
            raw=True,
        )

    def _log_time(self, topic: str, data: bytes) -> int:
        stamp = header_stamp_ns(data) if self._has_header[topic] else None
        if stamp is not None:
            self._latest_ns = stamp if self._latest_ns is None else max(self._latest_ns, stamp)
            return stamp
        if self._latest_ns is not None:
            return self._latest_ns
        return self.get_clock().now().nanoseconds

    def _on_message(self, topic: str, data: bytes) -> None:
        self._last[topic] = data
        log_time = self._log_time(topic, data)
        self._fg_channels[topic].log(data, log_time=log_time)
        if topic == names.MARKERS:
            self._server.broadcast_time(log_time)
        if topic == names.SCENE_MASSES and self._scene:
            self._publish_scene(log_time)

    def _resend_latched(self) -> None:
        for topic in self._latched:
            data = self._last.get(topic)
            if data is not None:
                self._fg_channels[topic].log(data, log_time=self._log_time(topic, data))

    def _decoded(self, topic: str) -> object | None:
        data = self._last.get(topic)
        if data is None:
            return None
        return deserialize_message(data, TOPIC_MESSAGE_CLASSES[topic])

    def _publish_scene(self, log_time: int) -> None:
        """Arrows, the base frame and the ground of the latest scene; skipped until
        odometry arrived.

        The true rate and inertia (``/splitter/truth/...``) when served, else the
        IMU's and ``/splitter/inertia``.
        """
        odom = self._decoded(names.ODOM)
        imu = self._decoded(names.TRUTH_IMU) or self._decoded(names.IMU)
        inertia = self._decoded(names.TRUTH_INERTIA) or self._decoded(names.INERTIA)
        if odom is None or imu is None or inertia is None:
            return
        pose = odom.pose.pose
        position = np.array([pose.position.x, pose.position.y, pose.position.z])
        q = pose.orientation
        w, inertia_v = imu.angular_velocity, inertia.vector
        wrenches = [self._decoded(t) for t in names.CONTACT_WRENCHES]
        contact = None
        if all(wr is not None for wr in wrenches):
            contact = [[wr.wrench.force.x, wr.wrench.force.y, wr.wrench.force.z] for wr in wrenches]
        try:
            scene = scene_from_pose(
                header_stamp_ns(self._last[names.SCENE_MASSES]) or 0,
                position,
                [q.w, q.x, q.y, q.z],
                mass_positions_world=masses_from_msg(self._decoded(names.SCENE_MASSES)),
                principal_inertia_kg_m2=[inertia_v.x, inertia_v.y, inertia_v.z],
                angular_velocity_rad_s=[w.x, w.y, w.z],
                contact_forces_n=contact,
            )
            arrows = scene.arrows
        except ValueError as exc:  # MessageValidationError too
            self.get_logger().warning(f"scene not drawn: {exc}", throttle_duration_sec=2.0)
            return
        stamp = odom.header.stamp
        self._scene_channel.log(serialize_message(arrow_markers(arrows, stamp)), log_time=log_time)
        transform = FrameTransform(
            timestamp=Timestamp(sec=int(stamp.sec), nsec=int(stamp.nanosec)),
            parent_frame_id=names.WORLD_FRAME,
            child_frame_id=names.BASE_FRAME,
            translation=Vector3(x=float(position[0]), y=float(position[1]), z=float(position[2])),
            rotation=Quaternion(x=float(q.x), y=float(q.y), z=float(q.z), w=float(q.w)),
        )
        self._tf_channel.log(FrameTransforms(transforms=[transform]), log_time=log_time)
        if self._ground_channel is not None:
            boxes = ground_boxes(self._ground, position)
            self._ground_channel.log(ground_scene_update(boxes, scene.t_ns), log_time=log_time)
        self.scene_count += 1

    def destroy_node(self) -> None:
        server = getattr(self, "_server", None)
        if server is not None:
            server.stop()
            self._server = None
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Run the node until Ctrl-C or shutdown; an invalid parameter or busy port exits with 1."""
    started = time.monotonic()
    return run_node(
        lambda stop: FoxgloveBridgeNode(),
        NODE_NAME,
        args,
        before_destroy=lambda node: node.get_logger().info(
            f"served {node.scene_count} scenes in {time.monotonic() - started:.1f} s"
        ),
    )


if __name__ == "__main__":
    raise SystemExit(main())
