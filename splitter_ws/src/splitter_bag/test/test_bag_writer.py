"""Bag writer round trips: mcap reader, rosbags reader, counts, splits, recovery of torn files."""

from __future__ import annotations

import array
import os
import struct
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from rclpy.serialization import serialize_message
from rosbags.rosbag2 import Reader as RosbagsReader
from rosbags.typesys import Stores, get_typestore

from splitter_bag import (
    BagWriter,
    BagWriterError,
    QosProfile,
    WriterOptions,
    read_mcap_statistics,
    read_messages,
    read_metadata,
    recover_bag,
)
from splitter_bag.core.info import check_consistency
from splitter_bag.core.metadata import parse_serialized_metadata
from splitter_bag.testing import complete_chunk_messages
from splitter_msgs_py import conversions as cv
from splitter_msgs_py import names

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
STEP_NS = 5_000_000  # [ns]


def assert_same_message(ros_msg: object, rosbags_msg: object, where: str = "msg") -> None:
    """Field-by-field equality of an rclpy message and a rosbags-deserialized one."""
    if hasattr(ros_msg, "get_fields_and_field_types"):
        for field in ros_msg.get_fields_and_field_types():
            assert_same_message(
                getattr(ros_msg, field), getattr(rosbags_msg, field), f"{where}.{field}"
            )
    elif isinstance(ros_msg, list | tuple | np.ndarray | array.array):
        ros_items = list(ros_msg)
        other = list(rosbags_msg)
        assert len(ros_items) == len(other), where
        for i, (a, b) in enumerate(zip(ros_items, other, strict=True)):
            assert_same_message(a, b, f"{where}[{i}]")
    elif isinstance(ros_msg, bytes) and isinstance(rosbags_msg, int):
        assert ros_msg == bytes([rosbags_msg]), where  # rclpy's byte fields are bytes
    else:
        assert ros_msg == rosbags_msg, f"{where}: {ros_msg!r} != {rosbags_msg!r}"


def sample_messages(n_steps: int) -> list[tuple[str, object, int, bytes]]:
    """(topic, rclpy message, t_ns, cdr) of a small run of the graph.

    Serialized once: Fast CDR leaves alignment padding uninitialised, so serializing
    the same message twice may give different bytes.
    """
    rng = np.random.default_rng(7)
    out: list[tuple[str, object, int]] = []
    for k in range(n_steps):
        t = k * STEP_NS
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        out.append((names.CLOCK, cv.clock_to_msg(t), t))
        out.append((names.IMU, cv.imu_to_msg(t, q, rng.normal(size=3), rng.normal(size=3)), t))
        out.append(
            (
                names.JOINT_STATES,
                cv.joint_state_to_msg(t, *rng.normal(size=(3, 25))),
                t,
            )
        )
        out.append(
            (names.ODOM, cv.odom_to_msg(t, rng.normal(size=3), q, rng.normal(size=3), q[1:]), t)
        )
        if k % 10 == 0:
            status = cv.DiagnosticStatusSample("sim: state", 1, "warn", {"energy_j": 1.5})
            out.append((names.DIAGNOSTICS, cv.diagnostics_to_msg(t, [status]), t))
    out.append((names.GAIT_PHASE, cv.message_class("std_msgs/msg/String")(data="IN_FLIGHT"), 0))
    return [(topic, msg, t, serialize_message(msg)) for topic, msg, t in out]


def write_bag(bag_dir: Path, messages, options: WriterOptions | None = None) -> dict[str, int]:
    counts: dict[str, int] = {}
    with BagWriter(bag_dir, options) as bag:
        for topic, _, t, cdr in messages:
            if not bag.has_topic(topic):
                bag.add_topic(topic, names.TOPIC_TYPES[topic], [QosProfile(depth=100)])
            bag.write(topic, cdr, t, t + 1)
            counts[topic] = counts.get(topic, 0) + 1
    return counts


def test_round_trip_with_mcap_and_rosbags_readers(tmp_path: Path) -> None:
    messages = sample_messages(120)
    bag_dir = tmp_path / "run"
    counts = write_bag(bag_dir, messages)

    # mcap: the exact bytes, times and order; one ros2msg schema per type, cdr channels.
    expected = sorted(((t, topic, cdr) for topic, _, t, cdr in messages), key=lambda x: x[0])
    got = list(read_messages(bag_dir))
    assert [(m.log_time_ns, m.topic, m.data) for m in got] == expected
    assert all(m.publish_time_ns == m.log_time_ns + 1 for m in got)
    assert all(m.type == names.TOPIC_TYPES[m.topic] for m in got)
    with open(bag_dir / "run_0.mcap", "rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
        assert len(summary.schemas) == len({names.TOPIC_TYPES[t] for t in counts})
        for channel in summary.channels.values():
            assert channel.message_encoding == "cdr"
            assert set(channel.metadata) == {"offered_qos_profiles", "topic_type_hash"}
            assert channel.metadata["topic_type_hash"].startswith("RIHS01_")
        assert {c.compression for c in summary.chunk_indexes} == {"zstd"}
        records = [m for m in reader.iter_metadata() if m.name == "rosbag2"]
    # rosbag2 writes its metadata record when a file opens and again before it closes.
    assert len(records) == 2
    final = parse_serialized_metadata(records[-1].metadata["serialized_metadata"])
    assert final == read_metadata(bag_dir)

    # rosbags (an independent rosbag2 implementation) with the Jazzy typestore.
    by_time = {(topic, t): msg for topic, msg, t, _ in messages}
    n = 0
    with RosbagsReader(bag_dir) as reader:
        assert {c.topic: c.msgcount for c in reader.connections} == counts
        for connection, timestamp, raw in reader.messages():
            decoded = TYPESTORE.deserialize_cdr(raw, connection.msgtype)
            assert_same_message(by_time[(connection.topic, timestamp)], decoded, connection.topic)
            n += 1
    assert n == len(messages)


def test_counts_agree_between_metadata_statistics_and_writes(tmp_path: Path) -> None:
    messages = sample_messages(50)
    bag_dir = tmp_path / "counts"
    counts = write_bag(bag_dir, messages)
    metadata = read_metadata(bag_dir)
    assert {t.topic_metadata.name: t.message_count for t in metadata.topics_with_message_count} == (
        counts
    )
    assert metadata.message_count == sum(counts.values()) == len(messages)
    stats = read_mcap_statistics(bag_dir / "counts_0.mcap")
    assert stats.channel_message_counts == counts
    assert stats.message_count == metadata.files[0].message_count == len(messages)
    assert metadata.starting_time_ns == stats.message_start_time_ns == 0
    assert metadata.duration_ns == stats.message_end_time_ns == 49 * STEP_NS
    assert check_consistency(bag_dir).ok


def test_split_by_size_and_duration(tmp_path: Path) -> None:
    messages = sample_messages(400)
    by_size = tmp_path / "size"
    counts = write_bag(
        by_size, messages, WriterOptions(chunk_size_bytes=4096, max_bagfile_size_bytes=40_000)
    )
    metadata = read_metadata(by_size)
    assert len(metadata.files) >= 3
    assert list(metadata.relative_file_paths) == [
        f"size_{i}.mcap" for i in range(len(metadata.files))
    ]
    assert sorted(p.name for p in by_size.glob("*.mcap")) == sorted(metadata.relative_file_paths)
    for info in metadata.files[:-1]:
        # rosbag2's rule: split before a write once the bytes written reach the threshold,
        # so each file's last chunk starts below it and ends at or above it.
        with open(by_size / info.path, "rb") as f:
            chunks = make_reader(f).get_summary().chunk_indexes
        last = max(chunks, key=lambda c: c.chunk_start_offset)
        assert last.chunk_start_offset < 40_000
        assert last.chunk_start_offset + last.chunk_length + last.message_index_length >= 40_000
    assert sum(f.message_count for f in metadata.files) == len(messages)
    assert check_consistency(by_size).ok
    assert [m.log_time_ns for m in read_messages(by_size)] == sorted(m[2] for m in messages)
    with RosbagsReader(by_size) as reader:
        assert {c.topic: c.msgcount for c in reader.connections} == counts
        assert sum(1 for _ in reader.messages()) == len(messages)

    by_time = tmp_path / "time"
    write_bag(by_time, messages, WriterOptions(max_bagfile_duration_ns=500_000_000))
    metadata = read_metadata(by_time)
    # 2 s of log time, a new file once a file spans more than 0.5 s (rosbag2's rule).
    assert len(metadata.files) == 4
    for info in metadata.files:
        assert info.duration_ns <= 500_000_000
    assert check_consistency(by_time).ok


def test_writer_refuses_misuse(tmp_path: Path) -> None:
    bag_dir = tmp_path / "bag"
    with BagWriter(bag_dir) as bag:
        with pytest.raises(BagWriterError, match="not added"):
            bag.write("/nope", b"\x00\x01\x00\x00", 0, 0)
        bag.add_topic(names.CLOCK, names.TOPIC_TYPES[names.CLOCK])
        with pytest.raises(ValueError, match="negative"):
            bag.write(names.CLOCK, serialize_message(cv.clock_to_msg(0)), -1, 0)
    with pytest.raises(BagWriterError, match="closed"):
        bag.write(names.CLOCK, b"", 0, 0)
    with pytest.raises(BagWriterError, match="already exists"):
        BagWriter(bag_dir)
    with pytest.raises(ValueError, match="1024"):
        WriterOptions(max_bagfile_size_bytes=100)
    # An empty bag is still a valid bag.
    assert read_metadata(bag_dir).message_count == 0
    assert check_consistency(bag_dir).ok


def record_spans(data: bytes) -> list[tuple[int, int]]:
    """(start, end) of each MCAP record after the leading magic: opcode, u64 length, body."""
    spans, at = [], 8
    while at + 9 <= len(data):
        (length,) = struct.unpack_from("<Q", data, at + 1)
        spans.append((at, at + 9 + length))
        at += 9 + length
    return spans


def test_a_cut_anywhere_in_a_record_is_a_torn_end(tmp_path: Path) -> None:
    """Cut inside the opcode, the length and the body of each record after the header.

    (A file cut inside its header is not an MCAP file; recovery refuses it.)
    """
    messages = sample_messages(60)
    bag_dir = tmp_path / "whole"
    write_bag(bag_dir, messages, WriterOptions(chunk_size_bytes=2048))
    data = (bag_dir / "whole_0.mcap").read_bytes()
    spans = record_spans(data)[1:17]
    assert len(spans) == 16
    for i, (start, end) in enumerate(spans):
        for cut in sorted({start + 1, start + 5, (start + end) // 2, end - 1}):
            torn = tmp_path / f"torn_{i}_{cut}"
            torn.mkdir()
            (torn / f"{torn.name}_0.mcap").write_bytes(data[:cut])
            survivors = complete_chunk_messages(torn / f"{torn.name}_0.mcap")
            recover_bag(torn)
            got = list(read_messages(torn))
            assert [m.data for m in got] == [m.data for m in survivors], (i, cut)


@pytest.mark.parametrize("kept_fraction", [0.35, 0.6, 0.61, 0.8])
def test_recover_torn_file_keeps_every_closed_chunk(tmp_path: Path, kept_fraction: float) -> None:
    messages = sample_messages(300)
    bag_dir = tmp_path / "torn"
    write_bag(bag_dir, messages, WriterOptions(chunk_size_bytes=8192))
    path = bag_dir / "torn_0.mcap"
    os.remove(bag_dir / "metadata.yaml")
    data = path.read_bytes()
    # Cut in the middle of the data section, as a SIGKILL mid-chunk leaves it.
    # Where the cut falls (a chunk, a message index, a record's length) depends on
    # the compressed sizes, so several places are cut.
    path.write_bytes(data[: int(len(data) * kept_fraction)])
    survivors = complete_chunk_messages(path)
    assert 0 < len(survivors) < len(messages)

    report = recover_bag(bag_dir)
    assert report.files[0].rewritten and not report.files[0].complete
    assert report.files[0].error  # why reading stopped is reported
    got = list(read_messages(bag_dir))
    assert [(m.log_time_ns, m.publish_time_ns, m.data) for m in got] == [
        (m.log_time, m.publish_time, m.data) for m in survivors
    ]
    # What survived is a prefix of what was written (the bag orders equal log times
    # by file position, which is the write order).
    written = [(t, cdr) for _, _, t, cdr in messages]
    assert [(m.log_time_ns, m.data) for m in got] == written[: len(got)]
    assert check_consistency(bag_dir).ok
    with RosbagsReader(bag_dir) as reader:
        assert sum(1 for _ in reader.messages()) == len(survivors)

    # Recovering a complete bag changes nothing.
    before = path.read_bytes()
    again = recover_bag(bag_dir)
    assert again.files[0].complete and not again.files[0].rewritten
    assert path.read_bytes() == before
    assert again.metadata == report.metadata


def test_empty_float64_sequences_decode_with_mcap_ros2_but_not_rosbags(tmp_path: Path) -> None:
    """Interoperability fact for whoever reads our bags with rosbags.

    Fast CDR 2 (Jazzy) aligns to 8 after the length of an empty float64 sequence;
    rclpy and mcap_ros2 (Foxglove's decoding scheme) read that, rosbags 0.11.9 does
    not. Publishers that want rosbags-readable bags fill velocity and effort.
    """
    from mcap_ros2.decoder import DecoderFactory
    from rclpy.serialization import deserialize_message
    from rosbags.serde import SerdeError

    msg = cv.joint_state_to_msg(0, np.arange(25.0))  # velocity and effort empty
    bag_dir = tmp_path / "joints"
    write_bag(bag_dir, [(names.JOINT_COMMANDS, msg, 0, serialize_message(msg))])
    (stored,) = list(read_messages(bag_dir))
    back = deserialize_message(stored.data, type(msg))
    assert list(back.position) == list(range(25)) and len(back.effort) == 0
    with open(bag_dir / "joints_0.mcap", "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        ((_, _, _, decoded),) = list(reader.iter_decoded_messages())
    assert list(decoded.position) == list(range(25)) and len(decoded.velocity) == 0
    with pytest.raises(SerdeError):
        TYPESTORE.deserialize_cdr(stored.data, "sensor_msgs/msg/JointState")


def test_node_parameters_ride_in_the_bag_as_attachments_and_survive_recovery(
    tmp_path: Path,
) -> None:
    from splitter_bag.core.node_parameters import (
        MEDIA_TYPE,
        attachment_name,
        bag_node_parameters,
        parameter_file_text,
    )
    from splitter_bag.core.reader import read_attachments

    params = {"q_w": [1.0, 2.0, 3.0], "objective": "momentum", "horizon": 25}
    text = parameter_file_text("inertial_morphing_mpc", params)
    messages = sample_messages(300)
    bag_dir = tmp_path / "with_params"
    with BagWriter(bag_dir, WriterOptions(chunk_size_bytes=8192)) as bag:
        bag.add_attachment(attachment_name("inertial_morphing_mpc"), text.encode(), MEDIA_TYPE)
        for topic, _, t, cdr in messages:
            if not bag.has_topic(topic):
                bag.add_topic(topic, names.TOPIC_TYPES[topic], [QosProfile(depth=100)])
            bag.write(topic, cdr, t, t)
    assert read_attachments(bag_dir) == {"params/inertial_morphing_mpc.yaml": text.encode()}
    assert bag_node_parameters(bag_dir) == {"inertial_morphing_mpc": params}
    with open(bag_dir / "with_params_0.mcap", "rb") as f:
        (attachment,) = make_reader(f).iter_attachments()
    assert attachment.media_type == "application/yaml"
    # rosbag2 readers ignore attachments: every message still reads back
    assert check_consistency(bag_dir).ok
    with RosbagsReader(bag_dir) as reader:
        assert sum(1 for _ in reader.messages()) == len(messages)
    # a recorder killed mid-run: the recovered bag still carries the parameters
    os.remove(bag_dir / "metadata.yaml")
    path = bag_dir / "with_params_0.mcap"
    path.write_bytes(path.read_bytes()[: int(path.stat().st_size * 0.6)])
    assert bag_node_parameters(bag_dir) == {"inertial_morphing_mpc": params}
    report = recover_bag(bag_dir)
    assert report.files[0].rewritten
    assert bag_node_parameters(bag_dir) == {"inertial_morphing_mpc": params}
    assert check_consistency(bag_dir).ok
