"""Read a rosbag2 MCAP bag directory back: metadata, per-file statistics, messages.

ROS-free: messages come back as serialized CDR bytes with their topic, type and
times; deserialize with ``rclpy.serialization.deserialize_message`` or a
``rosbags`` typestore.
"""

from __future__ import annotations

import heapq
import logging
import re
import struct
from collections.abc import Collection, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import zstandard
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Attachment
from mcap.stream_reader import StreamReader

from splitter_bag.core.metadata import (
    METADATA_FILENAME,
    BagMetadata,
    MetadataError,
    read_metadata,
)

_log = logging.getLogger(__name__)
_FILE_INDEX = re.compile(r"_(\d+)\.mcap$")


class BagMessage(NamedTuple):
    """One recorded message."""

    topic: str
    type: str  # "pkg/msg/Type"
    log_time_ns: int  # [ns] receive time (what a player schedules on)
    publish_time_ns: int  # [ns] source time
    data: bytes  # serialized CDR


@dataclass(frozen=True)
class McapStatistics:
    """What the summary section of one ``.mcap`` says."""

    path: Path
    profile: str
    library: str
    message_count: int
    message_start_time_ns: int
    message_end_time_ns: int
    chunk_count: int
    channel_message_counts: dict[str, int]  # by topic
    schemas: dict[str, tuple[str, str]]  # type -> (encoding, definition text)
    channel_metadata: dict[str, dict[str, str]]  # topic -> channel metadata
    channel_types: dict[str, str]  # topic -> type
    channel_encodings: dict[str, str]  # topic -> message encoding
    compressions: frozenset[str]  # chunk compressions used
    rosbag2_records: tuple[str, ...]  # serialized_metadata of every ``rosbag2`` record


def mcap_files(bag_dir: Path | str) -> list[Path]:
    """The bag's ``.mcap`` files in order: from metadata.yaml, else ``_<n>`` order."""
    bag_dir = Path(bag_dir)
    if (bag_dir / METADATA_FILENAME).is_file():
        metadata = read_metadata(bag_dir)
        return [bag_dir / p for p in metadata.relative_file_paths]
    return sorted_mcap_files(bag_dir)


def sorted_mcap_files(bag_dir: Path | str) -> list[Path]:
    """Every ``.mcap`` in ``bag_dir``, ordered by the split index ``_<n>``."""

    def key(p: Path) -> tuple[int, str]:
        m = _FILE_INDEX.search(p.name)
        return (int(m.group(1)) if m else -1, p.name)

    return sorted(Path(bag_dir).glob("*.mcap"), key=key)


def read_mcap_statistics(path: Path | str) -> McapStatistics:
    """Summary of a complete ``.mcap`` (raises if it has no summary: recover it first)."""
    path = Path(path)
    with open(path, "rb") as f:
        reader = make_reader(f)
        header = reader.get_header()
        summary = reader.get_summary()
        if summary is None or summary.statistics is None:
            raise MetadataError(f"{path} has no summary section (run 'splitter bag recover')")
        stats = summary.statistics
        records = tuple(
            m.metadata.get("serialized_metadata", "")
            for m in reader.iter_metadata()
            if m.name == "rosbag2"
        )
    channels = summary.channels
    schemas = summary.schemas
    counts: dict[str, int] = {}
    for channel_id, count in stats.channel_message_counts.items():
        topic = channels[channel_id].topic
        counts[topic] = counts.get(topic, 0) + count
    return McapStatistics(
        path=path,
        profile=header.profile,
        library=header.library,
        message_count=stats.message_count,
        message_start_time_ns=stats.message_start_time,
        message_end_time_ns=stats.message_end_time,
        chunk_count=stats.chunk_count,
        channel_message_counts=counts,
        schemas={s.name: (s.encoding, s.data.decode("utf-8")) for s in schemas.values()},
        channel_metadata={c.topic: dict(c.metadata) for c in channels.values()},
        channel_types={
            c.topic: schemas[c.schema_id].name if c.schema_id in schemas else ""
            for c in channels.values()
        },
        channel_encodings={c.topic: c.message_encoding for c in channels.values()},
        compressions=frozenset(ci.compression for ci in summary.chunk_indexes),
        rosbag2_records=records,
    )


def _file_messages(path: Path, topics: Collection[str] | None) -> Iterator[BagMessage]:
    with open(path, "rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages(
            topics=list(topics) if topics is not None else None, log_time_order=True
        ):
            yield BagMessage(
                channel.topic,
                schema.name if schema is not None else "",
                message.log_time,
                message.publish_time,
                message.data,
            )


def read_messages(
    bag_dir: Path | str,
    topics: Collection[str] | None = None,
    start_time_ns: int | None = None,
    end_time_ns: int | None = None,
) -> Iterator[BagMessage]:
    """Every message of the bag in log-time order (files merged), optionally filtered.

    ``topics`` selects topics (None = all); ``[start_time_ns, end_time_ns)`` bounds
    the log time. Files are streamed one message at a time.
    """
    files = mcap_files(bag_dir)
    if not files:
        raise MetadataError(f"{bag_dir} holds no .mcap file")
    streams = [_file_messages(p, topics) for p in files]
    # Split files are consecutive in time, but merging keeps the order exact regardless.
    for msg in heapq.merge(*streams, key=lambda m: m.log_time_ns):
        if start_time_ns is not None and msg.log_time_ns < start_time_ns:
            continue
        if end_time_ns is not None and msg.log_time_ns >= end_time_ns:
            continue
        yield msg


def read_attachments(bag_dir: Path | str) -> dict[str, bytes]:
    """name -> data of every MCAP attachment in the bag's files (the first of a name wins).

    Found through each file's summary; a file without a usable one (its recorder was
    killed) is read record by record up to where it is cut, so the attachments
    written before the cut still come back.
    """
    files = mcap_files(bag_dir)
    if not files:
        raise MetadataError(f"{bag_dir} holds no .mcap file")
    out: dict[str, bytes] = {}
    for path in files:
        for attachment in _file_attachments(path):
            out.setdefault(attachment.name, bytes(attachment.data))
    return out


_TORN = (McapError, EOFError, ValueError, KeyError, struct.error, zstandard.ZstdError)


def _file_attachments(path: Path) -> list[Attachment]:
    with open(path, "rb") as f:
        try:
            return list(make_reader(f).iter_attachments())
        except _TORN as exc:
            _log.warning("%s: no usable summary (%s): reading its records in order", path, exc)
    found = []
    with open(path, "rb") as f:
        try:
            for record in StreamReader(f).records:
                if isinstance(record, Attachment):
                    found.append(record)
        except _TORN as exc:
            _log.warning("%s: records end early (%s): attachments up to there", path, exc)
    return found


def topic_types(bag_dir: Path | str) -> dict[str, str]:
    """topic -> type of the bag (from metadata.yaml)."""
    topics = bag_metadata(bag_dir).topics_with_message_count
    return {t.topic_metadata.name: t.topic_metadata.type for t in topics}


def bag_metadata(bag_dir: Path | str) -> BagMetadata:
    """The bag's metadata.yaml."""
    return read_metadata(bag_dir)
