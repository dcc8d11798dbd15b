"""``graph_watchdog`` node: names a node of the graph that makes no progress.

Thin ROS layer over :class:`splitter_bringup.core.watchdog.GraphWatchdog`: it
subscribes to each watched node's progress topic, feeds the header stamps in, and
every ``check_period_s`` (wall) logs each stall it finds as one line
``STALLED <node>: <reason>`` (error in lockstep, warning in real time), which the
launcher reads (:mod:`splitter_bringup.launcher`). It publishes nothing.
"""

from __future__ import annotations

import time

import rclpy
from geometry_msgs.msg import Vector3Stamped, WrenchStamped
from rclpy.executors import ExternalShutdownException
from rclpy.logging import get_logger
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import Imu, JointState

from splitter_bringup.core.watchdog import (
    DEFAULT_STALL_TIMEOUT_S,
    PROGRESS_TOPICS,
    GraphWatchdog,
)
from splitter_msgs_py import names
from splitter_msgs_py.parameters import (
    InvalidParameterError,
    ParameterSpec,
    declare_parameters,
)
from splitter_msgs_py.qos import qos_for
from splitter_msgs_py.signals import StopRequest, spin_until_stopped

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
)


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


def main(args: list[str] | None = None) -> int:
    """Run the node until Ctrl-C or shutdown; an invalid parameter stops it with exit code 1."""
    stop = StopRequest()
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    node = None
    try:
        node = GraphWatchdogNode()
        spin_until_stopped(node, stop)
    except InvalidParameterError as exc:
        get_logger(NODE_NAME).fatal(f"invalid parameter, not starting: {exc}")
        return 1
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
