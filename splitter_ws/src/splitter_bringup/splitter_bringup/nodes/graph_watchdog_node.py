"""``graph_watchdog`` node: names a node of the graph that makes no progress.

Thin ROS layer over :class:`splitter_bringup.analysis.watchdog.GraphWatchdog`: it
subscribes to each watched node's progress topic, feeds the header stamps in, and
every ``check_period_s`` (wall) logs each stall it finds as one line
``STALLED <node>: <reason>`` (error in lockstep, warning in real time), which the
launcher reads (:mod:`splitter_bringup.run.launcher`).

It also lists, every ``foreign_check_period_s`` (wall), the publishers on the
graph's topics (:data:`splitter_msgs_py.names.TOPIC_TYPES`) and reports each one
the graph did not start (``graph_nodes``; :mod:`splitter_bringup.analysis.foreign_publishers`)
as one warning line ``FOREIGN publisher <node> on <topic>: <reason>``, which the
launcher counts, and on ``/diagnostics`` (``graph_watchdog: foreign publishers``,
WARN, stamped with the simulator's latest state) while any was seen.
"""

from __future__ import annotations

import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped, WrenchStamped
from rclpy.node import Node
from sensor_msgs.msg import Imu, JointState

from splitter_bringup.analysis.foreign_publishers import (
    ForeignPublisherTracker,
    qualified_name,
)
from splitter_bringup.analysis.watchdog import (
    DEFAULT_STALL_TIMEOUT_S,
    PROGRESS_TOPICS,
    SIMULATOR,
    GraphWatchdog,
)
from splitter_msgs_py import names
from splitter_msgs_py.conversions import DiagnosticStatusSample, diagnostics_to_msg
from splitter_msgs_py.node_pattern import run_node
from splitter_msgs_py.parameters import (
    InvalidParameterError,
    ParameterSpec,
    declare_parameters,
)
from splitter_msgs_py.qos import qos_for

NODE_NAME = "graph_watchdog"
STALL_PREFIX = "STALLED"  # the launcher matches "STALLED <node>: <reason>"
MESSAGE_TYPES = {
    names.IMU: Imu,
    names.JUMP_COMMAND: WrenchStamped,
    names.INERTIA_SETPOINT: Vector3Stamped,
    names.JOINT_COMMANDS: JointState,
}

PARAMETERS = (
    ParameterSpec(
        "watched_nodes",
        list(PROGRESS_TOPICS),
        "nodes whose progress is watched (the simulator among them)",
        item_type=str,
    ),
    ParameterSpec("lockstep", True, "lockstep graph (else real time)"),
    ParameterSpec(
        "stall_timeout_s",
        DEFAULT_STALL_TIMEOUT_S,
        "wall time without progress after which a node is stalled [s]",
        0.1,
        3600.0,
    ),
    ParameterSpec("check_period_s", 0.5, "wall period of the check [s]", 0.01, 60.0),
    ParameterSpec("control_period_s", 0.01, "control tick [s]", 0.001, 1.0),
    ParameterSpec(
        "graph_nodes",
        [],
        "names of every node the launcher started (empty: no foreign-publisher check)",
        item_type=str,
    ),
    ParameterSpec(
        "foreign_check_period_s",
        1.0,
        "wall period of the check for publishers the graph did not start [s]",
        0.05,
        60.0,
    ),
)
FOREIGN_DIAGNOSTICS = f"{NODE_NAME}: foreign publishers"


class GraphWatchdogNode(Node):
    """Feeds progress stamps to the core watchdog and logs the stalls it names."""

    def __init__(self, **kwargs) -> None:
        super().__init__(NODE_NAME, **kwargs)
        try:
            values = declare_parameters(self, PARAMETERS)
            self.watchdog = GraphWatchdog(
                tuple(values["watched_nodes"]),
                lockstep=bool(values["lockstep"]),
                stall_timeout_s=float(values["stall_timeout_s"]),
                control_period_ns=round(float(values["control_period_s"]) * 1e9),
            )
        except ValueError as exc:
            self.destroy_node()
            raise InvalidParameterError(f"watched_nodes / stall_timeout_s: {exc}") from exc
        self.stalls: list[str] = []
        for node in self.watchdog.nodes:
            topic = PROGRESS_TOPICS[node]
            self.create_subscription(
                MESSAGE_TYPES[topic],
                topic,
                lambda msg, node=node: self._on_progress(node, msg),
                qos_for(topic),
            )
        self.create_timer(float(values["check_period_s"]), self._check)
        self.foreign = ForeignPublisherTracker(tuple(values["graph_nodes"]))
        if values["graph_nodes"]:
            self._diagnostics = self.create_publisher(
                DiagnosticArray, names.DIAGNOSTICS, qos_for(names.DIAGNOSTICS)
            )
            self.create_timer(float(values["foreign_check_period_s"]), self._check_foreign)

    def _on_progress(self, node: str, msg: object) -> None:
        stamp = msg.header.stamp
        self.watchdog.on_output(node, stamp.sec * 1_000_000_000 + stamp.nanosec, time.monotonic())

    def _check(self) -> None:
        for stall in self.watchdog.check(time.monotonic()):
            line = f"{STALL_PREFIX} {stall.node}: {stall.reason}"
            self.stalls.append(line)
            if self.watchdog.lockstep:
                self.get_logger().error(line)
            else:
                self.get_logger().warning(line)

    def _check_foreign(self) -> None:
        for foreign in self.foreign.update(graph_publishers(self)):
            self.get_logger().warning(foreign.line())
        if self.foreign.count:
            topics = sorted({f.topic for f in self.foreign.found})
            status = DiagnosticStatusSample(
                FOREIGN_DIAGNOSTICS,
                1,
                f"{self.foreign.count} publishers the graph did not start",
                {"foreign_publishers": self.foreign.count, "topics": ", ".join(topics)},
            )
            stamp_ns = max(0, self.watchdog.stamp_ns(SIMULATOR))
            self._diagnostics.publish(diagnostics_to_msg(stamp_ns, [status]))


def graph_publishers(node: Node) -> dict[str, list[tuple[str, bytes]]]:
    """(fully qualified node name, endpoint GID) of every publisher on each graph topic."""
    return {
        topic: [
            (qualified_name(info.node_namespace, info.node_name), bytes(info.endpoint_gid))
            for info in node.get_publishers_info_by_topic(topic)
        ]
        for topic in names.TOPIC_TYPES
    }


def main(args: list[str] | None = None) -> int:
    """Run the node until Ctrl-C or shutdown; an invalid parameter stops it with exit code 1."""
    return run_node(lambda stop: GraphWatchdogNode(), NODE_NAME, args)


if __name__ == "__main__":
    raise SystemExit(main())
