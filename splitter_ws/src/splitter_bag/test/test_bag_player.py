"""Player node: timing, rate, offset, loop, topic selection, /clock and recorded QoS."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message

from splitter_bag import BagWriter, QosProfile
from splitter_bag.core.playback import PlaybackClock, parse_topic_list, select_topics
from splitter_bag.player_node import PlayerNode
from splitter_msgs_py import conversions as cv
from splitter_msgs_py.parameters import InvalidParameterError, ParameterValue

START_NS = 10_000_000_000  # [ns] bag start (log time)
A_PERIOD_NS = 50_000_000  # [ns]
B_PERIOD_NS = 100_000_000  # [ns]
SPAN_NS = 600_000_000  # [ns]
VECTOR_TYPE = "geometry_msgs/msg/Vector3Stamped"


@pytest.fixture(scope="module")
def bag(
    tmp_path_factory: pytest.TempPathFactory,
) -> tuple[Path, dict[str, list[tuple[int, bytes]]]]:
    bag_dir = tmp_path_factory.mktemp("player") / "bag"
    written: dict[str, list[tuple[int, bytes]]] = {"/test/a": [], "/test/b": []}
    with BagWriter(bag_dir) as writer:
        writer.add_topic("/test/a", VECTOR_TYPE, [QosProfile(depth=100)])
        writer.add_topic(
            "/test/b", VECTOR_TYPE, [QosProfile(depth=1, durability="transient_local")]
        )
        for t in range(START_NS, START_NS + SPAN_NS + 1, A_PERIOD_NS):
            for topic, period in (("/test/a", A_PERIOD_NS), ("/test/b", B_PERIOD_NS)):
                if (t - START_NS) % period == 0:
                    data = serialize_message(cv.vector3_to_msg(t, np.array([t * 1e-9, 0, 0])))
                    writer.write(topic, data, t, t)
                    written[topic].append((t, data))
    return bag_dir, written


class Listener:
    """Subscriber node that notes what arrives when (monotonic wall time)."""

    def __init__(self, context) -> None:
        from rclpy.node import Node

        self.node = Node("bag_listener", context=context)
        self.got: list[tuple[str, bytes, int]] = []
        self.clock: list[int] = []
        msg_type = cv.message_class(VECTOR_TYPE)
        for topic in ("/test/a", "/test/b"):
            self.node.create_subscription(
                msg_type,
                topic,
                lambda data, topic=topic: self.got.append((topic, data, time.monotonic_ns())),
                QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE),
                raw=True,
            )
        self.node.create_subscription(
            cv.message_class("rosgraph_msgs/msg/Clock"),
            "/clock",
            lambda msg: self.clock.append(cv.stamp_from_msg(msg.clock)),
            QoSProfile(depth=1000),
        )


def finished(player: PlayerNode, _: Listener) -> bool:
    """The player played the bag to its end."""
    return player.finished.is_set()


def play(
    context,
    bag_dir: Path,
    until: Callable[[PlayerNode, Listener], bool] = finished,
    timeout_s: float = 10.0,
    **params: ParameterValue,
) -> tuple[PlayerNode, Listener]:
    """Play ``bag_dir`` with ``params`` to a listener until ``until``; the player stopped."""
    listener = Listener(context)
    # Discovery on a loaded machine can take a while: 1 s before the first message.
    overrides = [Parameter("bag", value=str(bag_dir)), Parameter("start_delay_s", value=1.0)]
    overrides += [Parameter(k, value=v) for k, v in params.items()]
    player = PlayerNode(context=context, parameter_overrides=overrides)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(listener.node)
    executor.add_node(player)
    deadline = time.monotonic() + timeout_s
    try:
        while not until(player, listener):
            assert time.monotonic() < deadline, "playback did not complete in time"
            executor.spin_once(timeout_sec=0.005)
        for _ in range(20):  # deliveries still on their way
            executor.spin_once(timeout_sec=0.005)
    finally:
        player.stop()
    assert player.error is None
    return player, listener


def test_plays_selected_topic_with_original_timing_and_clock(ros_context, bag) -> None:
    bag_dir, written = bag
    player, listener = play(ros_context, bag_dir, topics="/test/a", clock_rate_hz=50.0)
    assert player.topics == ["/test/a"]
    assert [(topic, data) for topic, data, _ in listener.got] == [
        ("/test/a", data) for _, data in written["/test/a"]
    ]
    arrivals = np.array([t for _, _, t in listener.got]) - listener.got[0][2]
    expected = np.array([t for t, _ in written["/test/a"]]) - START_NS
    # Original timing: the span within 50 ms, each message within 100 ms (a 2-core CI
    # machine shared by other jobs); playing at a wrong rate would be off by 300 ms.
    assert abs(arrivals[-1] - expected[-1]) < 50e6
    assert np.max(np.abs(arrivals - expected)) < 100e6
    # /clock: the playback time, every 20 ms of bag time, up to the end of the bag.
    assert listener.clock == sorted(listener.clock)
    assert listener.clock[0] == START_NS and listener.clock[-1] == START_NS + SPAN_NS
    assert np.all(np.diff(listener.clock)[:-1] == 20_000_000)


def test_rate_and_start_offset(ros_context, bag) -> None:
    bag_dir, written = bag
    _, listener = play(
        ros_context, bag_dir, topics="/test/a", rate=2.0, start_offset_s=0.2, clock_rate_hz=0.0
    )
    expected = [(t, d) for t, d in written["/test/a"] if t >= START_NS + 200_000_000]
    assert [d for _, d, _ in listener.got] == [d for _, d in expected]
    span_s = (listener.got[-1][2] - listener.got[0][2]) * 1e-9
    assert span_s == pytest.approx(0.4 / 2.0, abs=0.06)  # 0.4 s of bag at rate 2
    assert listener.clock == []  # clock_rate_hz 0: no /clock


def test_loop_and_recorded_qos(ros_context, bag) -> None:
    bag_dir, written = bag
    n = len(written["/test/a"]) + len(written["/test/b"])
    player, listener = play(
        ros_context,
        bag_dir,
        lambda _, listener: len(listener.got) >= 2 * n + 3,
        rate=4.0,
        loop=True,
        clock_rate_hz=0.0,
    )
    assert player.loops_done >= 2
    for topic, messages in written.items():
        # Each topic in order, then again from the bag's start (two DDS writers: the
        # interleaving of equal log times across topics is not defined).
        got = [data for t, data, _ in listener.got if t == topic]
        once = [data for _, data in messages]
        assert got[: 2 * len(once)] == once + once
    offers = {
        topic: listener.node.get_publishers_info_by_topic(topic)[0].qos_profile
        for topic in ("/test/a", "/test/b")
    }
    assert offers["/test/b"].durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert offers["/test/a"].durability == DurabilityPolicy.VOLATILE
    assert offers["/test/a"].reliability == ReliabilityPolicy.RELIABLE


def test_player_requires_an_existing_bag(ros_context, tmp_path: Path) -> None:
    with pytest.raises(InvalidParameterError, match="bag"):
        PlayerNode(context=ros_context)
    with pytest.raises(InvalidParameterError, match="bag"):
        PlayerNode(context=ros_context, parameter_overrides=[Parameter("bag", value=str(tmp_path))])
    with pytest.raises(InvalidParameterError, match="rate"):
        PlayerNode(
            context=ros_context,
            parameter_overrides=[
                Parameter("bag", value=str(tmp_path)),
                Parameter("rate", value=0.0),
            ],
        )


def test_playback_clock_and_selection_are_pure_functions() -> None:
    clock = PlaybackClock(bag_start_ns=1_000, wall_start_ns=50_000, rate=2.0)
    assert clock.wall_time_ns(3_000) == 51_000
    assert clock.bag_time_ns(51_000) == 3_000
    with pytest.raises(ValueError):
        PlaybackClock(0, 0, rate=0.0)
    assert parse_topic_list(" /a, /b  /c,") == ["/a", "/b", "/c"]
    available = ["/splitter/imu", "/splitter/odom", "/clock", "/rosout"]
    assert select_topics(available) == sorted(available)
    assert select_topics(available, ["/clock"], regex="odom") == ["/clock", "/splitter/odom"]
    assert select_topics(available, exclude_regex="^/(rosout|clock)$") == [
        "/splitter/imu",
        "/splitter/odom",
    ]
