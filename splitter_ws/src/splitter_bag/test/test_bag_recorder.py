"""Recorder node: what is published is recorded, in-process and as a killed or stopped process."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile
from rclpy.serialization import deserialize_message, serialize_message

from splitter_bag import read_messages, read_metadata, recover_bag
from splitter_bag.core.info import check_consistency
from splitter_bag.recorder_node import RecorderNode
from splitter_bag.testing import complete_chunk_messages
from splitter_msgs_py import conversions as cv
from splitter_msgs_py import names, qos
from splitter_msgs_py.environment import ros_environment
from splitter_msgs_py.parameters import InvalidParameterError, ParameterValue
from splitter_msgs_py.testing import spin_until, spun_together

STEP_NS = 5_000_000  # [ns]


def imu_cdr(k: int) -> bytes:
    return serialize_message(cv.imu_to_msg(k * STEP_NS, [1, 0, 0, 0], [0.1 * k, 0, 0], [0, 0, 1]))


def _publisher(node, topic: str, profile: QoSProfile) -> Publisher:
    """A publisher of ``topic`` with its message type (``names.TOPIC_TYPES``)."""
    return node.create_publisher(cv.message_class(names.TOPIC_TYPES[topic]), topic, profile)


def _recorder(context, bag_dir: Path, **parameters: ParameterValue) -> RecorderNode:
    """The recorder writing ``bag_dir``, discovering topics every 50 ms."""
    overrides = [Parameter("output", value=str(bag_dir))]
    overrides += [Parameter(k, value=v) for k, v in parameters.items()]
    overrides.append(Parameter("discovery_period_s", value=0.05))
    return RecorderNode(context=context, parameter_overrides=overrides)


def test_records_graph_topics_with_offered_qos(ros_context, tmp_path: Path) -> None:
    from rclpy.node import Node

    bag_dir = tmp_path / "graph"
    source = Node("source", context=ros_context)
    recorder = _recorder(ros_context, bag_dir, regex="^/splitter/", exclude_regex="markers")
    with spun_together(ros_context, source, recorder) as executor:
        imu_pub = _publisher(source, names.IMU, qos.STATE_QOS)
        phase_pub = _publisher(source, names.GAIT_PHASE, qos.LATCHED_QOS)
        markers_pub = _publisher(source, names.MARKERS, qos.MARKERS_QOS)
        spin_until(
            executor,
            lambda: imu_pub.get_subscription_count() > 0 and phase_pub.get_subscription_count() > 0,
            10.0,
            "recorder subscription",
        )
        sent = []
        phase = cv.message_class("std_msgs/msg/String")(data="IN_FLIGHT")
        phase_pub.publish(phase)
        sent_phase = serialize_message(phase)
        for k in range(300):
            msg = cv.imu_to_msg(k * STEP_NS, [1, 0, 0, 0], [0.01 * k, 0.0, 0.0], [0.0, 0.0, 1.0])
            imu_pub.publish(msg)
            sent.append(msg)
            executor.spin_once(timeout_sec=0)
        spin_until(executor, lambda: recorder.message_counts.get(names.IMU, 0) == 300, 10.0, "IMU")
        assert names.MARKERS not in recorder.recorded_topics  # excluded by exclude_regex
        assert markers_pub.get_subscription_count() == 0
    # the recorder destroyed: its bag is closed

    metadata = read_metadata(bag_dir)
    assert {t.topic_metadata.name: t.message_count for t in metadata.topics_with_message_count} == {
        names.IMU: 300,
        names.GAIT_PHASE: 1,
    }
    imu_topic = metadata.topic(names.IMU).topic_metadata
    (offer,) = imu_topic.offered_qos_profiles
    assert (offer.reliability, offer.durability) == ("reliable", "volatile")
    (latched,) = metadata.topic(names.GAIT_PHASE).topic_metadata.offered_qos_profiles
    assert latched.durability == "transient_local"
    assert imu_topic.type_description_hash.startswith("RIHS01_")
    recorded = [m for m in read_messages(bag_dir) if m.topic == names.IMU]
    stamps = [m.publish_time_ns for m in recorded]
    assert stamps == [k * STEP_NS for k in range(300)]  # header stamps, in order
    for m, msg in zip(recorded, sent, strict=True):
        back = cv.imu_from_msg(deserialize_message(m.data, type(msg)))
        assert np.allclose(back.angular_velocity_rad_s, cv.imu_from_msg(msg).angular_velocity_rad_s)
    (phase_msg,) = [m for m in read_messages(bag_dir) if m.topic == names.GAIT_PHASE]
    assert phase_msg.data == sent_phase
    assert check_consistency(bag_dir).ok


def test_log_time_is_simulated_time_with_use_sim_time(ros_context, tmp_path: Path) -> None:
    from rclpy.node import Node

    bag_dir = tmp_path / "sim"
    source = Node("sim_source", context=ros_context)
    recorder = _recorder(
        ros_context, bag_dir, topics=f"{names.IMU}, {names.CLOCK}", use_sim_time=True
    )
    t_sim = 42 * 1_000_000_000
    with spun_together(ros_context, source, recorder) as executor:
        clock_pub = _publisher(source, names.CLOCK, qos.CLOCK_QOS)
        imu_pub = _publisher(source, names.IMU, qos.STATE_QOS)
        spin_until(executor, lambda: imu_pub.get_subscription_count() > 0, 10.0, "subscription")
        spin_until(executor, lambda: clock_pub.get_subscription_count() >= 2, 10.0, "clock subs")
        clock_pub.publish(cv.clock_to_msg(t_sim))
        now = recorder.get_clock().now
        spin_until(executor, lambda: now().nanoseconds == t_sim, 10.0, "sim time")
        imu_pub.publish(cv.imu_to_msg(t_sim - STEP_NS, [1, 0, 0, 0], [0, 0, 0], [0, 0, 0]))
        spin_until(executor, lambda: recorder.message_counts.get(names.IMU) == 1, 10.0, "IMU")
    (imu,) = [m for m in read_messages(bag_dir) if m.topic == names.IMU]
    assert imu.log_time_ns == t_sim  # receive time on the simulated clock
    assert imu.publish_time_ns == t_sim - STEP_NS  # header stamp


def test_invalid_parameters_stop_the_recorder(ros_context, tmp_path: Path) -> None:
    with pytest.raises(InvalidParameterError, match="regex"):
        _recorder(ros_context, tmp_path / "x", regex="(unclosed")
    with pytest.raises(InvalidParameterError, match="compression"):
        _recorder(ros_context, tmp_path / "y", compression="bz2")
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists()


# --- the recorder as a process -------------------------------------------------------


def _start_recorder(bag_dir: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [
            sys.executable,
            "-c",
            "from splitter_bag.recorder_node import main; main()",
            "--ros-args",
            "-p",
            f"output:={bag_dir}",
            "-p",
            f"topics:={names.IMU}",
            "-p",
            "chunk_size_bytes:=4096",
            "-p",
            "flush_period_s:=0.2",
            "-p",
            "discovery_period_s:=0.1",
        ],
        env=ros_environment(),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )


def _publish_to(proc: subprocess.Popen, ros_context, first: int, count: int, publisher=None):
    from rclpy.node import Node

    if publisher is None:
        node = Node("bag_test_publisher", context=ros_context)
        publisher = _publisher(node, names.IMU, qos.STATE_QOS)
        deadline = time.monotonic() + 20.0
        while publisher.get_subscription_count() == 0:
            assert proc.poll() is None, proc.stderr.read().decode()
            assert time.monotonic() < deadline, "the recorder process did not subscribe"
            time.sleep(0.05)
    sent = []
    for k in range(first, first + count):
        data = imu_cdr(k)
        publisher.publish(data)
        sent.append(data)
        time.sleep(0.001)
    return publisher, sent


@pytest.mark.parametrize("stop_signal", [signal.SIGINT, signal.SIGTERM])
def test_sigint_and_sigterm_finish_the_bag(ros_context, tmp_path: Path, stop_signal) -> None:
    bag_dir = tmp_path / "stopped"
    proc = _start_recorder(bag_dir)
    try:
        _, sent = _publish_to(proc, ros_context, 0, 200)
        time.sleep(0.5)  # reliable delivery of the last messages
        proc.send_signal(stop_signal)
        assert proc.wait(15) == 0, proc.stderr.read().decode()
    finally:
        if proc.poll() is None:
            proc.kill()
    metadata = read_metadata(bag_dir)  # written on the way out
    assert metadata.topic(names.IMU).message_count == 200
    assert [m.data for m in read_messages(bag_dir)] == sent
    assert check_consistency(bag_dir).ok


def test_kill_9_then_recover_gives_back_every_closed_chunk(ros_context, tmp_path: Path) -> None:
    bag_dir = tmp_path / "killed"
    proc = _start_recorder(bag_dir)
    try:
        publisher, first = _publish_to(proc, ros_context, 0, 200)
        time.sleep(0.8)  # > flush_period_s: everything so far is in closed chunks
        _, second = _publish_to(proc, ros_context, 200, 200, publisher)
        proc.kill()  # SIGKILL in the middle of recording
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert not (bag_dir / "metadata.yaml").exists()
    (path,) = bag_dir.glob("*.mcap")
    closed = complete_chunk_messages(path)

    report = recover_bag(bag_dir)
    recovered = list(read_messages(bag_dir))
    assert [m.data for m in recovered] == [m.data for m in closed]
    assert len(recovered) >= len(first)
    # What came back is everything sent up to some point: no gap, no reordering.
    sent = first + second
    assert [m.data for m in recovered] == sent[: len(recovered)]
    assert report.metadata.topic(names.IMU).message_count == len(recovered)
    assert check_consistency(bag_dir).ok
