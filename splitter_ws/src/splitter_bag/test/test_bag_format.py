"""The bag's text formats against rosbag2 Jazzy: YAML layout, metadata v9, definitions, info."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
import yaml

from splitter_bag.core import definitions, yamlcpp
from splitter_bag.core.info import format_bag_info, format_file_size
from splitter_bag.core.metadata import (
    DURATION_INFINITE_NS,
    BagMetadata,
    FileInformation,
    MetadataError,
    QosProfile,
    TopicInformation,
    TopicMetadata,
    parse_metadata_yaml,
    parse_qos_profiles,
    serialize_qos_profiles,
)

SEP = "=" * 80


def test_yaml_layout_is_yaml_cpp_block_style() -> None:
    doc = {
        "a": {"b": 1, "c": ""},
        "seq": [{"x": "y", "z": [1, 2]}, "plain"],
        "empty_seq": [],
        "nothing": None,
        "flag": False,
        "multi": "line1\nline2",
        "looks_like_int": "123",
    }
    expected = (
        'a:\n  b: 1\n  c: ""\n'
        "seq:\n  - x: y\n    z:\n      - 1\n      - 2\n  - plain\n"
        "empty_seq:\n  []\n"
        "nothing: ~\n"
        "flag: false\n"
        'multi: "line1\\nline2"\n'
        'looks_like_int: "123"'
    )
    text = yamlcpp.dump(doc)
    assert text == expected
    assert yaml.safe_load(text) == doc


def test_qos_profiles_serialize_like_rosbag2_version_9() -> None:
    profile = QosProfile(history="unknown", depth=0, durability="transient_local")
    text = serialize_qos_profiles([profile])
    # serialize_rclcpp_qos_vector(): a sequence, names for policies, {sec, nsec} durations.
    assert text.startswith("- history: unknown\n  depth: 0\n  reliability: reliable\n")
    assert "  durability: transient_local\n  deadline:\n    sec: 9223372036\n" in text
    assert text.endswith("  avoid_ros_namespace_conventions: false")
    assert parse_qos_profiles(text) == [profile]


def test_qos_profiles_of_metadata_version_8_are_read() -> None:
    # Version <= 8 stored integer rmw enums in a string (rosbag2 test bags of 2023).
    v8 = (
        "- history: 3\n  depth: 0\n  reliability: 1\n  durability: 2\n"
        "  deadline:\n    sec: 2147483647\n    nsec: 4294967295\n"
        "  lifespan:\n    sec: 10\n    nsec: 0\n  liveliness: 1\n"
        "  liveliness_lease_duration:\n    sec: 9223372036\n    nsec: 854775807\n"
        "  avoid_ros_namespace_conventions: false"
    )
    (p,) = parse_qos_profiles(v8)
    assert (p.history, p.reliability, p.durability, p.liveliness) == (
        "unknown",
        "reliable",
        "volatile",
        "automatic",
    )
    assert p.deadline_ns == DURATION_INFINITE_NS  # Fast DDS's Foxy "infinity" translated
    assert p.lifespan_ns == 10_000_000_000


def test_bad_qos_policy_is_rejected() -> None:
    with pytest.raises(MetadataError):
        parse_qos_profiles([{**QosProfile().to_node(), "reliability": "sometimes"}])


def _metadata() -> BagMetadata:
    topic = TopicMetadata(
        name="/splitter/imu",
        type="sensor_msgs/msg/Imu",
        offered_qos_profiles=(QosProfile(depth=100),),
        type_description_hash="RIHS01_" + "ab" * 32,
    )
    return BagMetadata(
        relative_file_paths=("run_0.mcap", "run_1.mcap"),
        files=(
            FileInformation("run_0.mcap", 5_000_000_000, 1_000_000_000, 3),
            FileInformation("run_1.mcap", 6_500_000_000, 500_000_000, 2),
        ),
        duration_ns=2_000_000_000,
        starting_time_ns=5_000_000_000,
        message_count=5,
        topics_with_message_count=(TopicInformation(topic, 5),),
        ros_distro="jazzy",
    )


def test_metadata_yaml_has_rosbag2_layout_and_round_trips() -> None:
    metadata = _metadata()
    text = metadata.metadata_yaml()
    lines = text.splitlines()
    assert lines[:3] == [
        "rosbag2_bagfile_information:",
        "  version: 9",
        "  storage_identifier: mcap",
    ]
    assert "  duration:\n    nanoseconds: 2000000000\n" in text
    assert "  starting_time:\n    nanoseconds_since_epoch: 5000000000\n" in text
    assert "    - topic_metadata:\n        name: /splitter/imu\n" in text
    assert "        offered_qos_profiles:\n          - history: keep_last\n" in text
    assert '  compression_format: ""\n  compression_mode: ""\n' in text
    assert "  custom_data: ~\n  ros_distro: jazzy" in text
    assert not text.endswith("\n")  # yaml-cpp writes no final newline
    keys = list(yaml.safe_load(text)["rosbag2_bagfile_information"])
    assert keys == [
        "version",
        "storage_identifier",
        "duration",
        "starting_time",
        "message_count",
        "topics_with_message_count",
        "compression_format",
        "compression_mode",
        "relative_file_paths",
        "files",
        "custom_data",
        "ros_distro",
    ]
    assert parse_metadata_yaml(text) == metadata


def test_unsupported_metadata_version_is_rejected() -> None:
    text = _metadata().metadata_yaml().replace("version: 9", "version: 3")
    with pytest.raises(MetadataError, match="version 3"):
        parse_metadata_yaml(text)


def _msg_text(type_name: str) -> str:
    package, name = definitions.split_type_name(type_name)
    return (definitions.package_share_directory(package) / "msg" / f"{name}.msg").read_text()


def test_definition_is_concatenated_like_rosbag2() -> None:
    d = definitions.message_definition("geometry_msgs/msg/Vector3Stamped")
    # Root first; dependencies depth first in sorted order of their names as written
    # ("Vector3" in geometry_msgs -> geometry_msgs/Vector3), each once.
    expected = (
        _msg_text("geometry_msgs/msg/Vector3Stamped")
        + f"\n{SEP}\nMSG: geometry_msgs/Vector3\n"
        + _msg_text("geometry_msgs/msg/Vector3")
        + f"\n{SEP}\nMSG: std_msgs/Header\n"
        + _msg_text("std_msgs/msg/Header")
        + f"\n{SEP}\nMSG: builtin_interfaces/Time\n"
        + _msg_text("builtin_interfaces/msg/Time")
    )
    assert d.encoding == "ros2msg"
    assert d.encoded_message_definition == expected


def test_definition_lists_each_dependency_once() -> None:
    text = definitions.message_definition(
        "visualization_msgs/msg/MarkerArray"
    ).encoded_message_definition
    headers = [line for line in text.splitlines() if line.startswith("MSG: ")]
    assert len(headers) == len(set(headers))
    assert "MSG: visualization_msgs/Marker" in headers
    assert "MSG: builtin_interfaces/Time" in headers


def test_unknown_type_gets_an_empty_unknown_definition() -> None:
    d = definitions.message_definition("no_such_pkg/msg/Nothing")
    assert (d.encoding, d.encoded_message_definition) == ("unknown", "")
    assert definitions.type_description_hash("no_such_pkg/msg/Nothing") == ""


def test_type_hashes_recompute_from_installed_descriptions() -> None:
    share = definitions.package_share_directory("sensor_msgs").parent
    checked = 0
    for path in sorted(share.glob("*_msgs/msg/*.json")):
        data = json.loads(path.read_text())
        stored = data["type_hashes"][0]["hash_string"]
        assert definitions.compute_type_hash(data["type_description_msg"]) == stored, path
        checked += 1
    assert checked > 50
    assert definitions.type_description_hash("geometry_msgs/msg/Vector3Stamped") == (
        "RIHS01_d4829622288cbb443886e7ea94ea5671a3b1be6bab4ad04224432a65f7d7887a"
    )


def test_header_detection_and_stamp_extraction() -> None:
    from rclpy.serialization import serialize_message

    from splitter_msgs_py import conversions as cv

    assert definitions.starts_with_header("sensor_msgs/msg/Imu")
    assert not definitions.starts_with_header("rosgraph_msgs/msg/Clock")
    assert not definitions.starts_with_header("std_msgs/msg/String")
    t_ns = 12_345_678_901
    cdr = serialize_message(cv.imu_to_msg(t_ns, [1, 0, 0, 0], [0, 0, 0], [0, 0, 0]))
    assert definitions.header_stamp_ns(cdr) == t_ns
    assert definitions.header_stamp_ns(b"\x00\x01") is None


def test_info_text_matches_ros2_bag_info(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TZ", "UTC")
    time.tzset()
    try:
        text = format_bag_info(_metadata(), 56_789)
    finally:
        monkeypatch.delenv("TZ")
        time.tzset()
    assert text.splitlines() == [
        "",
        "Files:             run_0.mcap",
        "                   run_1.mcap",
        "Bag size:          55.5 KiB",
        "Storage id:        mcap",
        "ROS Distro:        jazzy",
        "Duration:          2.000000000s",
        "Start:             Jan  1 1970 00:00:05.000000000 (5.000000000)",
        "End:               Jan  1 1970 00:00:07.000000000 (7.000000000)",
        "Messages:          5",
        "Topic information: Topic: /splitter/imu | Type: sensor_msgs/msg/Imu | Count: 5 | "
        "Serialization Format: cdr",
        "Service:           0",
        "Service information: ",
    ]
    assert format_file_size(512) == "512 B"
    assert format_file_size(3 * 1024**3) == "3.0 GiB"


def test_config_files_declare_every_node_parameter() -> None:
    from splitter_bag import player_node, recorder_node

    config = Path(__file__).resolve().parents[1] / "config"
    for node_module, file_name in ((recorder_node, "recorder.yaml"), (player_node, "player.yaml")):
        params = yaml.safe_load((config / file_name).read_text())[node_module.NODE_NAME][
            "ros__parameters"
        ]
        for spec in node_module.PARAMETERS:
            assert spec.name in params, f"{file_name} lacks {spec.name}"
            assert spec.validate(params[spec.name]) == params[spec.name]
