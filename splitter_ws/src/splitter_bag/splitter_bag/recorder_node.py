"""``recorder``: record the graph's topics into a rosbag2 MCAP bag (raw CDR, no deserialization).

Topics are found by periodic discovery (``get_topic_names_and_types``): every
topic with a publisher by default, or those listed in ``topics`` and/or matching
``regex``. Each is subscribed raw with a request compatible with every offer
(rosbag2's ``adapt_request_to_offers``), reliable and deep enough to keep up
with the graph; the publishers' offered QoS profiles and type hash go into the
bag. Log time is the receive time read on the node's clock when the callback
runs (simulated time with ``use_sim_time``, like rosbag2; rosbag2 takes the
middleware's receive timestamp otherwise, which only a message-info callback
sees). Publish time is the ``header.stamp`` of stamped types, else the log time
(``publish_time: header``), or the middleware's source timestamp
(``source_timestamp``, what rosbag2 Jazzy stores).
``node_parameters`` (the launcher gives every node's parameter file) go into
the bag as MCAP attachments (:mod:`splitter_bag.core.node_parameters`).
SIGINT and SIGTERM finish the bag (summary, metadata.yaml).
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rclpy.clock import Clock, ClockType
from rclpy.executors import Executor
from rclpy.logging import get_logger
from rclpy.node import Node
from rclpy.parameter import Parameter

from splitter_bag.core import definitions
from splitter_bag.core.node_parameters import (
    MEDIA_TYPE,
    ParameterFileError,
    attachment_name,
    parse_parameter_file,
)
from splitter_bag.core.playback import seconds_to_ns, select_topics
from splitter_bag.core.writer import BagWriter, WriterOptions
from splitter_bag.ros_params import (
    declare_key_values,
    declare_string_list,
    declare_topic_list,
)
from splitter_bag.ros_qos import offered_qos_profiles, subscription_qos, type_hash_of
from splitter_msgs_py.conversions import message_class
from splitter_msgs_py.executors import make_executor
from splitter_msgs_py.node_pattern import run_node
from splitter_msgs_py.parameters import InvalidParameterError, ParameterSpec, declare_parameters
from splitter_msgs_py.signals import StopRequest, drain, spin_until_stopped

NODE_NAME = "recorder"

PARAMETERS = (
    ParameterSpec(
        "output",
        "",
        "bag directory to create (must not exist); empty: rosbag2_<date>-<time> here",
    ),
    ParameterSpec(
        "regex", "", "also record topics matching this regular expression (both empty: all)"
    ),
    ParameterSpec("exclude_regex", "", "never record topics matching this regular expression"),
    ParameterSpec(
        "include_hidden_topics", False, "record hidden topics (a name part starting with '_')"
    ),
    ParameterSpec(
        "discovery_period_s", 0.5, "period of topic discovery [s]", min_value=0.01, max_value=60.0
    ),
    ParameterSpec(
        "queue_depth",
        1000,
        "subscription history depth per topic (reliable, keeps up with bursts)",
        min_value=1,
        max_value=1_000_000,
    ),
    ParameterSpec(
        "max_bagfile_size_bytes",
        0,
        "split when a file reaches this size [B] (0: never; else >= 1024)",
        min_value=0,
        max_value=2**62,
    ),
    ParameterSpec(
        "max_bagfile_duration_s",
        0.0,
        "split when a file spans this much log time [s] (0: never)",
        min_value=0.0,
        max_value=1e9,
    ),
    ParameterSpec(
        "chunk_size_bytes",
        768 * 1024,
        "MCAP chunk size [B]: at most this much is lost if the recorder is killed",
        min_value=1024,
        max_value=2**31,
    ),
    ParameterSpec("compression", "zstd", "MCAP chunk compression", choices=("zstd", "none")),
    ParameterSpec(
        "flush_period_s",
        1.0,
        "a chunk is closed and flushed at the latest this long after it opened [s]",
        min_value=0.01,
        max_value=3600.0,
    ),
    ParameterSpec(
        "publish_time",
        "header",
        "MCAP publish time: header.stamp of stamped types (else the log time), "
        "or the middleware's source timestamp as rosbag2 stores it",
        choices=("header", "source_timestamp"),
    ),
)


def _parameter_files(texts: list[str]) -> dict[str, str]:
    """node -> parameter-file text of the ``node_parameters`` items (InvalidParameterError)."""
    out = {}
    for text in texts:
        try:
            node, _ = parse_parameter_file(text)
        except ParameterFileError as exc:
            raise InvalidParameterError(f"parameter 'node_parameters': {exc}") from exc
        if node in out:
            raise InvalidParameterError(f"parameter 'node_parameters': node {node!r} twice")
        out[node] = text.rstrip("\n") + "\n"  # the list item may come stripped
    return out


def default_bag_name() -> str:
    """``rosbag2_YYYY_MM_DD-HH_MM_SS`` as ``ros2 bag record`` names a bag."""
    return time.strftime("rosbag2_%Y_%m_%d-%H_%M_%S")


def is_hidden(topic: str) -> bool:
    return any(part.startswith("_") for part in topic.split("/"))


class RecorderNode(Node):
    """Records the selected topics of the graph into one bag until destroyed."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        p = declare_parameters(self, PARAMETERS)
        self._params = p
        self._listed = declare_topic_list(
            self, "topics", "topics to record (none and no regex: every topic)"
        )
        custom_data = declare_key_values(
            self, "custom_data", "KEY=VALUE pairs stored in the bag's custom_data"
        )
        node_parameters = declare_string_list(
            self,
            "node_parameters",
            "ROS 2 parameter files (YAML text, one node each) stored in the bag as the MCAP "
            "attachments params/<node>.yaml",
        )
        for pattern_name in ("regex", "exclude_regex"):
            try:
                re.compile(str(p[pattern_name]))
            except re.error as exc:
                raise InvalidParameterError(
                    f"parameter '{pattern_name}': invalid regular expression: {exc}"
                ) from exc
        self._use_sim_time = bool(self.get_parameter("use_sim_time").value)  # for the log
        self._header_publish_time = p["publish_time"] == "header"
        options = WriterOptions(
            chunk_size_bytes=int(p["chunk_size_bytes"]),
            compression=str(p["compression"]),
            flush_period_s=float(p["flush_period_s"]),
            max_bagfile_size_bytes=int(p["max_bagfile_size_bytes"]),
            max_bagfile_duration_ns=seconds_to_ns(float(p["max_bagfile_duration_s"])),
            custom_data=custom_data,
        )
        self._recording: dict[str, Any] = {}
        self._skipped: set[str] = set()
        output = str(p["output"]) or default_bag_name()
        parameter_files = _parameter_files(node_parameters)
        self.writer = BagWriter(Path(output), options)
        try:
            for node, text in parameter_files.items():
                self.writer.add_attachment(attachment_name(node), text.encode("utf-8"), MEDIA_TYPE)
            steady = Clock(clock_type=ClockType.STEADY_TIME)
            self._discovery_timer = self.create_timer(
                float(p["discovery_period_s"]), self.discover, clock=steady
            )
            self._flush_timer = self.create_timer(
                min(0.5, float(p["flush_period_s"]) / 2.0), self.writer.flush_if_due, clock=steady
            )
            self.get_logger().info(
                f"recording into {self.writer.bag_dir} "
                f"({'simulated' if self._use_sim_time else 'receive'} time as log time)"
            )
            self.discover()
        except BaseException:
            self.writer.close()
            raise

    @property
    def bag_dir(self) -> Path:
        return self.writer.bag_dir

    @property
    def recorded_topics(self) -> list[str]:
        return sorted(self._recording)

    @property
    def message_counts(self) -> dict[str, int]:
        return self.writer.message_counts

    def discover(self) -> None:
        """Subscribe to every selected topic that has appeared since the last call."""
        if self.writer.closed:
            return
        p = self._params
        graph = dict(self.get_topic_names_and_types())
        candidates = [
            t
            for t in graph
            if t not in self._recording
            and t not in self._skipped
            and (p["include_hidden_topics"] or not is_hidden(t))
        ]
        chosen = select_topics(candidates, self._listed, str(p["regex"]), str(p["exclude_regex"]))
        for topic in chosen:
            types = graph[topic]
            if len(types) != 1:
                self.get_logger().warning(f"not recording {topic}: several types {types}")
                self._skipped.add(topic)
                continue
            endpoints = self.get_publishers_info_by_topic(topic)
            if not endpoints:
                continue  # subscribers only so far: wait for a publisher to learn its QoS
            self._record(topic, types[0], endpoints)

    def _record(self, topic: str, type_name: str, endpoints: list[Any]) -> None:
        try:
            msg_type = message_class(type_name)
        except (ValueError, ImportError) as exc:
            self.get_logger().warning(f"not recording {topic}: type {type_name} unknown ({exc})")
            self._skipped.add(topic)
            return
        type_hash = type_hash_of(endpoints)
        self.writer.add_topic(
            topic,
            type_name,
            offered_qos_profiles(endpoints),
            type_description_hash=type_hash,
        )
        qos = subscription_qos(endpoints, int(self._params["queue_depth"]))
        self._recording[topic] = self.create_subscription(
            msg_type, topic, self._callback(topic, type_name), qos, raw=True
        )
        self.get_logger().info(f"subscribed to {topic} [{type_name}]")

    @property
    def needs_message_info(self) -> bool:
        """True when callbacks take the middleware's message info (source timestamps).

        rclpy's EventsExecutor (much faster) cannot deliver message info, so
        :func:`main` uses it only when this is False.
        """
        return not self._header_publish_time

    def _callback(self, topic: str, type_name: str) -> Callable[..., None]:
        writer = self.writer
        clock = self.get_clock()
        header_stamp = self._header_publish_time and definitions.starts_with_header(type_name)

        if self.needs_message_info:

            def on_message_with_info(data: bytes, info: dict) -> None:
                if not writer.closed:
                    log_ns = clock.now().nanoseconds
                    writer.write(topic, data, log_ns, int(info["source_timestamp"]))

            return on_message_with_info

        def on_message(data: bytes) -> None:
            if not writer.closed:
                log_ns = clock.now().nanoseconds
                stamp = definitions.header_stamp_ns(data) if header_stamp else None
                writer.write(topic, data, log_ns, log_ns if stamp is None else stamp)

        return on_message

    def close(self) -> None:
        """Finish the bag (idempotent): the node records nothing afterwards."""
        if not self.writer.closed:
            metadata = self.writer.close()
            # After SIGTERM the context is shut down: log without /rosout then.
            logger = self.get_logger() if self.context.ok() else get_logger("splitter_bag")
            if metadata is not None:
                logger.info(
                    f"bag {self.writer.bag_dir} closed: {metadata.message_count} messages "
                    f"on {len(metadata.topics_with_message_count)} topics"
                )

    def destroy_node(self) -> None:
        self.close()
        super().destroy_node()


def recorder_executor(node: RecorderNode) -> Executor:
    """The project's executor, but rclpy's classic one when message info is needed."""
    executor = make_executor(node.context, "single_threaded" if node.needs_message_info else None)
    executor.add_node(node)
    return executor


def _record_until_stopped(node: RecorderNode, stop: StopRequest) -> None:
    executor = recorder_executor(node)
    spin_until_stopped(node, stop, executor=executor)
    if node.context.ok():
        # The launcher stops the recorder after the other nodes: take what they sent last.
        late = drain(executor, lambda: sum(node.writer.message_counts.values()))
        node.get_logger().info(f"drained {late} messages still queued at the stop")


def run(parameter_overrides: list[Parameter] | None = None, args: list[str] | None = None) -> int:
    """Record until SIGINT / SIGTERM, then finish the bag; the body of :func:`main`."""
    return run_node(
        lambda stop: RecorderNode(parameter_overrides=parameter_overrides or []),
        NODE_NAME,
        args,
        spin=_record_until_stopped,
    )


def main(args: list[str] | None = None) -> None:
    run(args=args)


if __name__ == "__main__":
    main()
