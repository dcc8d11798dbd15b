"""``player``: replay a rosbag2 MCAP bag with its original timing (raw CDR, no deserialization).

Messages are published when their log time comes due on a monotonic wall clock
scaled by ``rate``, from ``start_offset_s`` after the bag's start, optionally in
a loop, on the selected topics, each offered with the QoS it was recorded with
(rosbag2's ``adapt_offer_to_recorded_offers``). ``/clock`` carries the playback
time at ``clock_rate_hz`` (the recorded ``/clock`` is then not replayed, so that
the clock has a single source); with ``clock_rate_hz: 0`` nothing is added.
Playback runs on its own thread so that timing does not depend on the executor.
"""

from __future__ import annotations

import re
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message

from splitter_bag.core.metadata import read_metadata
from splitter_bag.core.playback import (
    PlaybackClock,
    seconds_to_ns,
    select_topics,
)
from splitter_bag.core.reader import BagMessage, read_messages
from splitter_bag.ros_params import declare_topic_list
from splitter_bag.ros_qos import publisher_qos
from splitter_msgs_py import names, qos
from splitter_msgs_py.conversions import clock_to_msg, message_class
from splitter_msgs_py.node_pattern import run_node
from splitter_msgs_py.parameters import InvalidParameterError, ParameterSpec, declare_parameters
from splitter_msgs_py.signals import spin_until_stopped

NODE_NAME = "player"
_NS_PER_S = 1_000_000_000

PARAMETERS = (
    ParameterSpec("bag", "", "bag directory to play (required)"),
    ParameterSpec("rate", 1.0, "playback rate factor", min_value=1e-3, max_value=1e3),
    ParameterSpec("loop", False, "start again from start_offset_s at the end"),
    ParameterSpec(
        "start_offset_s",
        0.0,
        "skip this much bag time from the start [s]",
        min_value=0.0,
        max_value=1e9,
    ),
    ParameterSpec("regex", "", "also play topics matching this regex (both empty: all)"),
    ParameterSpec("exclude_regex", "", "never play topics matching this regex"),
    ParameterSpec(
        "clock_rate_hz",
        100.0,
        "publish the playback time on /clock at this rate [Hz] (0: do not)",
        min_value=0.0,
        max_value=10_000.0,
    ),
    ParameterSpec(
        "publisher_depth", 1000, "history depth of each publisher", min_value=1, max_value=100_000
    ),
    ParameterSpec(
        "start_delay_s",
        0.5,
        "wait this long after creating the publishers, for discovery [s]",
        min_value=0.0,
        max_value=60.0,
    ),
)


class PlayerNode(Node):
    """Plays one bag from a background thread; ``finished`` is set at the end (no loop)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        p = declare_parameters(self, PARAMETERS)
        if not p["bag"]:
            raise InvalidParameterError("parameter 'bag': a bag directory is required")
        for key in ("regex", "exclude_regex"):
            try:
                re.compile(str(p[key]))
            except re.error as exc:
                raise InvalidParameterError(f"parameter '{key}': invalid regex: {exc}") from exc
        self.bag_dir = Path(str(p["bag"]))
        try:
            self.metadata = read_metadata(self.bag_dir)
        except ValueError as exc:
            raise InvalidParameterError(f"parameter 'bag': {exc}") from exc
        self.rate = float(p["rate"])
        self.loop = bool(p["loop"])
        self._clock_period_ns = (
            round(_NS_PER_S / float(p["clock_rate_hz"])) if p["clock_rate_hz"] > 0 else 0
        )
        recorded = {t.topic_metadata.name: t for t in self.metadata.topics_with_message_count}
        selected = select_topics(
            recorded,
            declare_topic_list(self, "topics", "topics to play (none and no regex: all)"),
            str(p["regex"]),
            str(p["exclude_regex"]),
        )
        if self._clock_period_ns and names.CLOCK in selected:
            selected.remove(names.CLOCK)
            self.get_logger().info("not replaying the recorded /clock: publishing playback time")
        self._publishers_by_topic: dict[str, Any] = {}
        for topic in selected:
            info = recorded[topic].topic_metadata
            try:
                msg_type = message_class(info.type)
            except (ValueError, ImportError) as exc:
                self.get_logger().warning(f"not playing {topic}: type {info.type} unknown ({exc})")
                continue
            profile = publisher_qos(info.offered_qos_profiles, int(p["publisher_depth"]), topic)
            self._publishers_by_topic[topic] = self.create_publisher(msg_type, topic, profile)
        self._clock_publisher = (
            self.create_publisher(
                message_class(names.TOPIC_TYPES[names.CLOCK]), names.CLOCK, qos.CLOCK_QOS
            )
            if self._clock_period_ns
            else None
        )
        self.start_ns = self.metadata.starting_time_ns + seconds_to_ns(float(p["start_offset_s"]))
        self.end_ns = self.metadata.end_time_ns
        self.published: dict[str, int] = dict.fromkeys(self._publishers_by_topic, 0)
        self.loops_done = 0
        self.finished = threading.Event()
        self._stop = threading.Event()
        self._start_delay_s = float(p["start_delay_s"])
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="bag_player", daemon=True)
        self.get_logger().info(
            f"playing {self.bag_dir} ({len(self._publishers_by_topic)} topics, "
            f"rate {self.rate}, {'loop' if self.loop else 'once'})"
        )
        self._thread.start()

    @property
    def topics(self) -> list[str]:
        return sorted(self._publishers_by_topic)

    @property
    def error(self) -> BaseException | None:
        """What stopped playback early, if anything."""
        return self._error

    # -- playback thread ------------------------------------------------------------
    def _messages(self) -> Iterator[BagMessage]:
        return read_messages(
            self.bag_dir, topics=list(self._publishers_by_topic), start_time_ns=self.start_ns
        )

    def _wait_until(self, wall_ns: int) -> bool:
        """Sleep until ``wall_ns`` (monotonic); False when asked to stop."""
        delay = (wall_ns - time.monotonic_ns()) / _NS_PER_S
        return not (delay > 0 and self._stop.wait(delay)) and not self._stop.is_set()

    def _publish_clock(self, bag_ns: int) -> None:
        if self._clock_publisher is not None:
            self._clock_publisher.publish(serialize_message(clock_to_msg(max(bag_ns, 0))))

    def _run(self) -> None:
        try:
            if self._stop.wait(self._start_delay_s):
                return
            while not self._stop.is_set():
                self._play_once()
                if not self.loop or self._stop.is_set():
                    break
                self.loops_done += 1
            self.get_logger().info(f"playback finished: {sum(self.published.values())} messages")
        except BaseException as exc:  # reported through error and the log, never dropped
            self._error = exc
            self.get_logger().error(f"playback stopped: {exc!r}")
        finally:
            self.finished.set()

    def _play_once(self) -> None:
        clock = PlaybackClock(self.start_ns, time.monotonic_ns(), self.rate)
        next_clock_ns = self.start_ns
        for msg in self._messages():
            # Clock ticks due before this message.
            while self._clock_period_ns and next_clock_ns <= msg.log_time_ns:
                if not self._wait_until(clock.wall_time_ns(next_clock_ns)):
                    return
                self._publish_clock(next_clock_ns)
                next_clock_ns += self._clock_period_ns
            if not self._wait_until(clock.wall_time_ns(msg.log_time_ns)):
                return
            self._publishers_by_topic[msg.topic].publish(msg.data)
            self.published[msg.topic] += 1
        if self._clock_period_ns and next_clock_ns <= self.end_ns + self._clock_period_ns:
            if self._wait_until(clock.wall_time_ns(self.end_ns)):
                self._publish_clock(self.end_ns)

    # -- lifecycle --------------------------------------------------------------------
    def stop(self, timeout_s: float = 5.0) -> None:
        """Stop playback and wait for the thread."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout_s)

    def destroy_node(self) -> None:
        self.stop()
        super().destroy_node()


def run(parameter_overrides: list[Parameter] | None = None, args: list[str] | None = None) -> int:
    """Play until the end (or SIGINT / SIGTERM); the body of :func:`main`. 1 on a playback error."""
    return run_node(
        lambda stop: PlayerNode(parameter_overrides=parameter_overrides or []),
        NODE_NAME,
        args,
        spin=lambda node, stop: spin_until_stopped(node, stop, finished=node.finished.is_set),
        exit_code=lambda node: 1 if node.error is not None else 0,
    )


def main(args: list[str] | None = None) -> None:
    run(args=args)


if __name__ == "__main__":
    main()
