"""Run a scenario's whole node graph inside one process with one executor.

The graph-level tests use it: the very nodes and parameters the launcher starts
as processes (``core.graph_config``), created in one rclpy context and spun by
one executor (the project's, :mod:`splitter_msgs_py.executors`), plus a probe
node recording every message as serialized bytes, so that runs can be compared
payload for payload. :func:`create_node` is also how ``splitter launch
--in-process`` (:mod:`splitter_bringup.run.inprocess_launch`) builds its nodes.
"""

from __future__ import annotations

import importlib
import time
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field

import rclpy
from rclpy.context import Context
from rclpy.executors import Executor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message

from splitter_bringup.scenario.definition import Scenario
from splitter_bringup.scenario.graph_config import NodeLaunch, graph_nodes
from splitter_msgs_py import names
from splitter_msgs_py.conversions import TOPIC_MESSAGE_CLASSES, stamp_from_msg
from splitter_msgs_py.executors import make_executor
from splitter_msgs_py.qos import qos_for

REMOVE_DRAIN_S = 0.2  # [s] executor turns between removing a node and destroying it


@dataclass
class GraphRecord:
    """Every message seen by the probe: topic -> list of CDR payloads, in arrival order."""

    payloads: dict[str, list[bytes]] = field(default_factory=lambda: defaultdict(list))

    def messages(self, topic: str) -> list:
        """The messages of ``topic``, deserialized."""
        cls = TOPIC_MESSAGE_CLASSES[topic]
        return [deserialize_message(p, cls) for p in self.payloads.get(topic, [])]

    def last_clock_ns(self) -> int:
        """Simulated time of the last /clock message (0 when none)."""
        clocks = self.messages(names.CLOCK)
        return stamp_from_msg(clocks[-1].clock) if clocks else 0


class ProbeNode(Node):
    """Subscribes raw to every graph topic and keeps the payloads."""

    def __init__(self, record: GraphRecord, topics: tuple[str, ...], **kwargs) -> None:
        super().__init__("graph_probe", **kwargs)
        self._subs = [
            self.create_subscription(
                TOPIC_MESSAGE_CLASSES[topic],
                topic,
                lambda data, t=topic: record.payloads[t].append(bytes(data)),
                qos_for(topic),
                raw=True,
            )
            for topic in topics
        ]


def create_node(launch: NodeLaunch, context: Context) -> Node:
    """The node of ``launch`` (its class and parameters) in ``context``."""
    module, name = launch.node_class.split(":")
    node_class = getattr(importlib.import_module(module), name)
    overrides = [Parameter(k, value=v) for k, v in launch.parameters.items()]
    remaps = launch.remapping_args()
    if not remaps:
        return node_class(context=context, parameter_overrides=overrides)
    return node_class(
        context=context, parameter_overrides=overrides, cli_args=["--ros-args", *remaps]
    )


@dataclass
class InProcessGraph:
    """The nodes of a scenario in one context; spin with :meth:`run_until`."""

    context: Context
    nodes: dict[str, Node]
    record: GraphRecord
    executor: Executor

    def remove(self, name: str) -> None:
        """Destroy one node mid-run (e.g. the MPC) and keep spinning the others."""
        node = self.nodes.pop(name)
        for timer in node.timers:
            timer.cancel()
        self.executor.remove_node(node)
        # rclpy's EventsExecutor may still hold events of the node's timers and
        # subscriptions: let it run them out before the node is destroyed under them
        deadline = time.monotonic() + REMOVE_DRAIN_S
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.01)
        node.destroy_node()

    def run_until(
        self,
        stop: Callable[[GraphRecord], bool],
        timeout_s: float = 120.0,
    ) -> bool:
        """Spin until ``stop(record)`` is true (True) or ``timeout_s`` wall seconds pass."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)
            if stop(self.record):
                return True
        return False

    def shutdown(self) -> None:
        """Destroy every node and the executor."""
        for node in list(self.nodes.values()):
            self.executor.remove_node(node)
            node.destroy_node()
        self.nodes.clear()
        self.executor.shutdown()


def start_graph(
    scenario: Scenario,
    context: Context,
    topics: tuple[str, ...] = tuple(names.TOPIC_TYPES),
) -> InProcessGraph:
    """Create every node of ``scenario`` (no recorder) and a probe in ``context``."""
    if not rclpy.ok(context=context):
        raise RuntimeError("start_graph needs an initialised rclpy context")
    record = GraphRecord()
    executor = make_executor(context)
    nodes: dict[str, Node] = {}
    probe = ProbeNode(record, topics, context=context)
    executor.add_node(probe)
    nodes["graph_probe"] = probe
    for launch in graph_nodes(scenario):
        node = create_node(launch, context)
        executor.add_node(node)
        nodes[launch.name] = node
    return InProcessGraph(context, nodes, record, executor)


def clock_reached(t_s: float) -> Callable[[GraphRecord], bool]:
    """A stop condition: simulated time reached ``t_s``."""
    target_ns = round(t_s * 1e9)

    def stop(record: GraphRecord) -> bool:
        payloads = record.payloads.get(names.CLOCK)
        if not payloads:
            return False
        clock = deserialize_message(payloads[-1], TOPIC_MESSAGE_CLASSES[names.CLOCK])
        return stamp_from_msg(clock.clock) >= target_ns

    return stop


def record_graph(
    scenario: Scenario,
    context: Context,
    recorder_parameters: dict,
    record_s: float,
    timeout_s: float = 180.0,
) -> GraphRecord:
    """Fly ``scenario`` in process with a recorder node until ``record_s`` of simulated time.

    The simulator is removed first and what is in flight drained, then the recorder
    closes its bag. Returns what the probe saw. Raises ``TimeoutError`` when the
    flight does not reach ``record_s`` within ``timeout_s`` (wall).
    """
    from splitter_bag.recorder_node import RecorderNode

    graph = start_graph(scenario, context)
    try:
        recorder = RecorderNode(
            context=context,
            parameter_overrides=[Parameter(k, value=v) for k, v in recorder_parameters.items()],
        )
        graph.executor.add_node(recorder)
        try:
            if not graph.run_until(clock_reached(record_s), timeout_s=timeout_s):
                raise TimeoutError(f"the graph did not reach t = {record_s} s in {timeout_s} s")
            graph.remove("simulator")
            for _ in range(200):
                graph.executor.spin_once(timeout_sec=0.01)
        finally:
            graph.executor.remove_node(recorder)
            recorder.close()
            recorder.destroy_node()
        return graph.record
    finally:
        graph.shutdown()
