"""rosbag2 bag metadata (``metadata.yaml``, version 9) as rosbag2_storage serializes it.

ROS-free. Field names, order and encodings follow rosbag2 Jazzy
(rosbag2_storage ``bag_metadata.hpp``, ``yaml.hpp``, ``qos.cpp``):

* ``metadata.yaml`` is ``{rosbag2_bagfile_information: <BagMetadata>}``; the MCAP
  ``rosbag2`` metadata record holds the bare ``<BagMetadata>`` under the key
  ``serialized_metadata``.
* Version 9 writes ``offered_qos_profiles`` as a YAML sequence of profiles whose
  policies are strings (``keep_last``, ``reliable``, ``transient_local``,
  ``automatic``; ``unknown`` for an unknown policy); the MCAP channel metadata holds
  the same sequence dumped to a string. Versions 4 to 8 held a string with integer
  policies; both are read.
* Durations are ``{sec, nsec}`` (rmw_time_t), infinite = ``{9223372036, 854775807}``.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import yaml

from splitter_bag.core import yamlcpp

METADATA_FILENAME = "metadata.yaml"
METADATA_VERSION = 9
STORAGE_IDENTIFIER = "mcap"
ROS_DISTRO = "jazzy"
MCAP_METADATA_NAME = "rosbag2"  # name of the MCAP metadata record
MCAP_METADATA_KEY = "serialized_metadata"
TIME_POINT_MAX_NS = 2**63 - 1  # std::chrono::nanoseconds::max(): "no message yet"
DURATION_INFINITE_NS = 2**63 - 1  # RMW_DURATION_INFINITE [ns]
_NS_PER_S = 1_000_000_000

# rmw_qos_*_policy_to_str() names; index = the rmw enum value (rclpy enums have the same values).
HISTORY_NAMES = ("system_default", "keep_last", "keep_all", "unknown")
RELIABILITY_NAMES = ("system_default", "reliable", "best_effort", "unknown", "best_available")
DURABILITY_NAMES = ("system_default", "transient_local", "volatile", "unknown", "best_available")
LIVELINESS_NAMES = (
    "system_default",
    "automatic",
    "manual_by_node",
    "manual_by_topic",
    "unknown",
    "best_available",
)


class MetadataError(ValueError):
    """A metadata.yaml that is missing, malformed or of an unsupported version."""


@dataclass(frozen=True)
class QosProfile:
    """One offered QoS profile as rosbag2 stores it (policies by rmw name)."""

    history: str = "keep_last"
    depth: int = 10
    reliability: str = "reliable"
    durability: str = "volatile"
    deadline_ns: int = DURATION_INFINITE_NS  # [ns]
    lifespan_ns: int = DURATION_INFINITE_NS  # [ns]
    liveliness: str = "automatic"
    liveliness_lease_duration_ns: int = DURATION_INFINITE_NS  # [ns]
    avoid_ros_namespace_conventions: bool = False

    def to_node(self) -> dict[str, Any]:
        """The version-9 YAML mapping (rosbag2's key order)."""
        return {
            "history": self.history,
            "depth": self.depth,
            "reliability": self.reliability,
            "durability": self.durability,
            "deadline": _rmw_time(self.deadline_ns),
            "lifespan": _rmw_time(self.lifespan_ns),
            "liveliness": self.liveliness,
            "liveliness_lease_duration": _rmw_time(self.liveliness_lease_duration_ns),
            "avoid_ros_namespace_conventions": self.avoid_ros_namespace_conventions,
        }

    @classmethod
    def from_node(cls, node: Mapping[str, Any]) -> QosProfile:
        """Read a profile in the version-9 (names) or older (integers) layout."""
        try:
            return cls(
                history=_policy(node["history"], HISTORY_NAMES),
                depth=int(node["depth"]),
                reliability=_policy(node["reliability"], RELIABILITY_NAMES),
                durability=_policy(node["durability"], DURABILITY_NAMES),
                deadline_ns=_rmw_time_ns(node["deadline"]),
                lifespan_ns=_rmw_time_ns(node["lifespan"]),
                liveliness=_policy(node["liveliness"], LIVELINESS_NAMES),
                liveliness_lease_duration_ns=_rmw_time_ns(node["liveliness_lease_duration"]),
                avoid_ros_namespace_conventions=bool(node["avoid_ros_namespace_conventions"]),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise MetadataError(f"malformed QoS profile {dict(node)!r}: {exc}") from exc


def _rmw_time(ns: int) -> dict[str, int]:
    return {"sec": ns // _NS_PER_S, "nsec": ns % _NS_PER_S}


# Foxy-era "infinite" durations that rosbag2 translates to RMW_DURATION_INFINITE (qos.cpp).
_FOXY_INFINITIES = {(0x7FFFFFFF, 0xFFFFFFFF), (0x7FFFFFFF, 0x7FFFFFFF), (9223372036, 854775807)}


def _rmw_time_ns(node: Mapping[str, Any]) -> int:
    sec, nsec = int(node["sec"]), int(node["nsec"])
    if (sec, nsec) in _FOXY_INFINITIES or sec * _NS_PER_S + nsec >= DURATION_INFINITE_NS:
        return DURATION_INFINITE_NS
    return sec * _NS_PER_S + nsec


def _policy(value: Any, names: Sequence[str]) -> str:
    if isinstance(value, bool):
        raise ValueError(f"QoS policy {value!r} is neither a name nor an rmw enum value")
    if isinstance(value, int):
        if not 0 <= value < len(names):
            raise ValueError(f"QoS policy value {value} out of range")
        return names[value]
    text = str(value).lower()
    if text not in names:
        raise ValueError(f"unknown QoS policy {value!r} (one of {names})")
    return text


def qos_profiles_to_node(profiles: Sequence[QosProfile]) -> list[dict[str, Any]]:
    """The version-9 ``offered_qos_profiles`` sequence."""
    return [p.to_node() for p in profiles]


def serialize_qos_profiles(profiles: Sequence[QosProfile]) -> str:
    """``rosbag2_storage::serialize_rclcpp_qos_vector`` (version 9): the MCAP channel metadata."""
    return yamlcpp.dump(qos_profiles_to_node(profiles))


def parse_qos_profiles(value: str | Sequence[Mapping[str, Any]] | None) -> list[QosProfile]:
    """Profiles from a version-9 sequence or a serialized string (any version)."""
    if value is None or value == "":
        return []
    if isinstance(value, str):
        try:
            value = yaml.safe_load(value)
        except yaml.YAMLError as exc:
            raise MetadataError(f"offered_qos_profiles is not YAML: {exc}") from exc
        if value is None:
            return []
    if not isinstance(value, list):
        raise MetadataError(f"offered_qos_profiles must be a sequence, got {value!r}")
    return [QosProfile.from_node(p) for p in value]


@dataclass(frozen=True)
class TopicMetadata:
    """rosbag2_storage::TopicMetadata (the id is the storage's and is not serialized)."""

    name: str
    type: str  # "pkg/msg/Type"
    serialization_format: str = "cdr"
    offered_qos_profiles: tuple[QosProfile, ...] = ()
    type_description_hash: str = ""  # "RIHS01_<64 hex>" or ""

    def to_node(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "type": self.type,
            "serialization_format": self.serialization_format,
            "offered_qos_profiles": qos_profiles_to_node(self.offered_qos_profiles),
            "type_description_hash": self.type_description_hash,
        }


@dataclass(frozen=True)
class TopicInformation:
    topic_metadata: TopicMetadata
    message_count: int = 0


@dataclass(frozen=True)
class FileInformation:
    path: str  # relative to the bag directory
    starting_time_ns: int = TIME_POINT_MAX_NS  # [ns] first log time in the file
    duration_ns: int = 0  # [ns]
    message_count: int = 0


@dataclass(frozen=True)
class BagMetadata:
    """rosbag2_storage::BagMetadata (``bag_size`` is not serialized and not kept)."""

    version: int = METADATA_VERSION
    storage_identifier: str = STORAGE_IDENTIFIER
    relative_file_paths: tuple[str, ...] = ()
    files: tuple[FileInformation, ...] = ()
    duration_ns: int = 0  # [ns]
    starting_time_ns: int = TIME_POINT_MAX_NS  # [ns]
    message_count: int = 0
    topics_with_message_count: tuple[TopicInformation, ...] = ()
    compression_format: str = ""
    compression_mode: str = ""
    custom_data: Mapping[str, str] = field(default_factory=dict)
    ros_distro: str = ROS_DISTRO

    def to_node(self) -> dict[str, Any]:
        """The mapping ``YAML::convert<BagMetadata>::encode`` builds (version 9 layout)."""
        return {
            "version": self.version,
            "storage_identifier": self.storage_identifier,
            "duration": {"nanoseconds": self.duration_ns},
            "starting_time": {"nanoseconds_since_epoch": self.starting_time_ns},
            "message_count": self.message_count,
            "topics_with_message_count": [
                {"topic_metadata": t.topic_metadata.to_node(), "message_count": t.message_count}
                for t in self.topics_with_message_count
            ],
            "compression_format": self.compression_format,
            "compression_mode": self.compression_mode,
            "relative_file_paths": list(self.relative_file_paths),
            "files": [
                {
                    "path": f.path,
                    "starting_time": {"nanoseconds_since_epoch": f.starting_time_ns},
                    "duration": {"nanoseconds": f.duration_ns},
                    "message_count": f.message_count,
                }
                for f in self.files
            ],
            # yaml-cpp emits an empty unordered_map as a null node.
            "custom_data": dict(self.custom_data) if self.custom_data else None,
            "ros_distro": self.ros_distro,
        }

    def serialized(self) -> str:
        """The ``serialized_metadata`` value of the MCAP ``rosbag2`` record."""
        return yamlcpp.dump(self.to_node())

    def metadata_yaml(self) -> str:
        """The text of ``metadata.yaml``."""
        return yamlcpp.dump({"rosbag2_bagfile_information": self.to_node()})

    @property
    def end_time_ns(self) -> int:
        return self.starting_time_ns + self.duration_ns if self.message_count else 0

    def topic(self, name: str) -> TopicInformation:
        for info in self.topics_with_message_count:
            if info.topic_metadata.name == name:
                return info
        raise KeyError(name)

    def with_counts(self, counts: Mapping[str, int]) -> BagMetadata:
        """A copy whose topics carry ``counts`` (topics not listed keep theirs)."""
        topics = tuple(
            replace(t, message_count=counts.get(t.topic_metadata.name, t.message_count))
            for t in self.topics_with_message_count
        )
        return replace(
            self,
            topics_with_message_count=topics,
            message_count=sum(t.message_count for t in topics),
        )


def _get(node: Mapping[str, Any], key: str, where: str) -> Any:
    if key not in node:
        raise MetadataError(f"{where}: missing '{key}'")
    return node[key]


def metadata_from_node(node: Mapping[str, Any]) -> BagMetadata:
    """Parse a ``BagMetadata`` mapping of version 4 to 9 (as rosbag2's decoder does)."""
    where = "rosbag2_bagfile_information"
    version = int(_get(node, "version", where))
    if not 4 <= version <= METADATA_VERSION:
        raise MetadataError(f"{where}: unsupported metadata version {version}")
    topics = []
    for item in _get(node, "topics_with_message_count", where) or []:
        tm = _get(item, "topic_metadata", where)
        topics.append(
            TopicInformation(
                TopicMetadata(
                    name=str(_get(tm, "name", where)),
                    type=str(_get(tm, "type", where)),
                    serialization_format=str(_get(tm, "serialization_format", where)),
                    offered_qos_profiles=tuple(parse_qos_profiles(tm.get("offered_qos_profiles"))),
                    type_description_hash=str(tm.get("type_description_hash") or ""),
                ),
                int(_get(item, "message_count", where)),
            )
        )
    files = tuple(
        FileInformation(
            path=str(f["path"]),
            starting_time_ns=int(f["starting_time"]["nanoseconds_since_epoch"]),
            duration_ns=int(f["duration"]["nanoseconds"]),
            message_count=int(f["message_count"]),
        )
        for f in node.get("files") or []
    )
    custom = node.get("custom_data") or {}
    return BagMetadata(
        version=version,
        storage_identifier=str(_get(node, "storage_identifier", where)),
        relative_file_paths=tuple(str(p) for p in _get(node, "relative_file_paths", where)),
        files=files,
        duration_ns=int(_get(node, "duration", where)["nanoseconds"]),
        starting_time_ns=int(_get(node, "starting_time", where)["nanoseconds_since_epoch"]),
        message_count=int(_get(node, "message_count", where)),
        topics_with_message_count=tuple(topics),
        compression_format=str(node.get("compression_format") or ""),
        compression_mode=str(node.get("compression_mode") or ""),
        custom_data={str(k): str(v) for k, v in custom.items()},
        ros_distro=str(node.get("ros_distro") or ""),
    )


def parse_metadata_yaml(text: str) -> BagMetadata:
    """Parse the text of a ``metadata.yaml``."""
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise MetadataError(f"metadata.yaml is not YAML: {exc}") from exc
    if not isinstance(doc, Mapping) or "rosbag2_bagfile_information" not in doc:
        raise MetadataError("metadata.yaml has no 'rosbag2_bagfile_information'")
    return metadata_from_node(doc["rosbag2_bagfile_information"])


def parse_serialized_metadata(text: str) -> BagMetadata:
    """Parse the ``serialized_metadata`` of an MCAP ``rosbag2`` record."""
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise MetadataError(f"serialized_metadata is not YAML: {exc}") from exc
    if not isinstance(doc, Mapping):
        raise MetadataError("serialized_metadata is not a mapping")
    return metadata_from_node(doc)


def read_metadata(bag_dir: Path | str) -> BagMetadata:
    """Read ``<bag_dir>/metadata.yaml``."""
    path = Path(bag_dir) / METADATA_FILENAME
    if not path.is_file():
        raise MetadataError(f"{path} does not exist (run 'splitter bag recover {bag_dir}'?)")
    return parse_metadata_yaml(path.read_text(encoding="utf-8"))


def write_metadata(bag_dir: Path | str, metadata: BagMetadata) -> Path:
    """Write ``<bag_dir>/metadata.yaml`` atomically (temporary file, then rename)."""
    path = Path(bag_dir) / METADATA_FILENAME
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w", encoding="utf-8") as f:
        f.write(metadata.metadata_yaml())
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    return path


def ros_distro() -> str:
    """``ROS_DISTRO`` of the environment, Jazzy when unset (the PyPI wheels do not set it)."""
    return os.environ.get("ROS_DISTRO") or ROS_DISTRO
