"""``ros2 bag info``'s text for a bag, and a consistency check of its files (ROS-free).

The layout follows rosbag2_py ``format_bag_meta_data`` (Jazzy): 19-column labels,
times as ``%b %e %Y %H:%M:%S.<ns>`` local time with seconds since the epoch, sizes
in binary units with one decimal.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from splitter_bag.core.metadata import BagMetadata, read_metadata
from splitter_bag.core.reader import read_mcap_statistics

_INDENT = " " * 19
_NS_PER_S = 1_000_000_000


def format_file_size(size_bytes: int) -> str:
    size = float(size_bytes)
    units = ("B", "KiB", "MiB", "GiB", "TiB")
    index = 0
    while size >= 1024 and index < 4:
        size /= 1024
        index += 1
    return f"{size:.0f} {units[index]}" if index == 0 else f"{size:.1f} {units[index]}"


def _seconds(ns: int) -> str:
    return f"{ns // _NS_PER_S}.{ns % _NS_PER_S:09d}"


def format_time_point(ns: int) -> str:
    t = time.localtime(ns // _NS_PER_S)
    date = time.strftime("%b %e %Y", t)
    clock = time.strftime("%H:%M:%S", t)
    return f"{date} {clock}.{ns % _NS_PER_S:09d} ({_seconds(ns)})"


def bag_size_bytes(bag_dir: Path | str) -> int:
    """Size of the files in the bag directory (rcutils_calculate_directory_size)."""
    return sum(p.stat().st_size for p in Path(bag_dir).iterdir() if p.is_file())


def format_bag_info(metadata: BagMetadata, size_bytes: int) -> str:
    """The text ``ros2 bag info`` prints for ``metadata``."""
    lines = [""]
    paths = list(metadata.relative_file_paths)
    lines.append("Files:             " + (paths[0] if paths else ""))
    lines += [_INDENT + p for p in paths[1:]]
    lines.append("Bag size:          " + format_file_size(size_bytes))
    lines.append("Storage id:        " + metadata.storage_identifier)
    lines.append("ROS Distro:        " + (metadata.ros_distro or "unknown"))
    lines.append("Duration:          " + _seconds(metadata.duration_ns) + "s")
    start = metadata.starting_time_ns
    lines.append("Start:             " + format_time_point(start))
    lines.append("End:               " + format_time_point(start + metadata.duration_ns))
    lines.append(f"Messages:          {metadata.message_count}")
    topics = [
        f"Topic: {t.topic_metadata.name} | Type: {t.topic_metadata.type} | "
        f"Count: {t.message_count} | Serialization Format: {t.topic_metadata.serialization_format}"
        for t in metadata.topics_with_message_count
    ]
    lines.append("Topic information: " + (topics[0] if topics else ""))
    lines += [_INDENT + t for t in topics[1:]]
    lines.append("Service:           0")
    lines.append("Service information: ")
    return "\n".join(lines)


@dataclass(frozen=True)
class ConsistencyReport:
    """metadata.yaml against the MCAP summaries of the bag's files."""

    problems: tuple[str, ...]
    mcap_counts: dict[str, int]  # by topic, summed over files

    @property
    def ok(self) -> bool:
        return not self.problems


def check_consistency(bag_dir: Path | str) -> ConsistencyReport:
    """Compare counts and times of metadata.yaml with every file's MCAP statistics."""
    bag_dir = Path(bag_dir)
    metadata = read_metadata(bag_dir)
    problems = []
    totals: dict[str, int] = {}
    for info in metadata.files:
        stats = read_mcap_statistics(bag_dir / info.path)
        if stats.profile != "ros2":
            problems.append(f"{info.path}: MCAP profile {stats.profile!r}, not 'ros2'")
        if stats.message_count != info.message_count:
            problems.append(
                f"{info.path}: {stats.message_count} messages in MCAP statistics, "
                f"{info.message_count} in metadata.yaml"
            )
        if info.message_count and stats.message_start_time_ns != info.starting_time_ns:
            problems.append(f"{info.path}: start time differs from MCAP statistics")
        for topic, n in stats.channel_message_counts.items():
            totals[topic] = totals.get(topic, 0) + n
    for t in metadata.topics_with_message_count:
        name = t.topic_metadata.name
        if totals.get(name, 0) != t.message_count:
            problems.append(
                f"{name}: {totals.get(name, 0)} messages in MCAP statistics, "
                f"{t.message_count} in metadata.yaml"
            )
    if sum(totals.values()) != metadata.message_count:
        problems.append(
            f"{sum(totals.values())} messages in the files, {metadata.message_count} in metadata"
        )
    return ConsistencyReport(tuple(problems), totals)
