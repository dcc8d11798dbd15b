"""Turn a bag whose recorder died (SIGKILL, power loss) into a complete bag.

ROS-free. A recorder killed without finishing leaves ``.mcap`` files without a
summary section (and possibly cut in the middle of a record) and no
``metadata.yaml``. Every record up to the first incomplete one is read
sequentially (what ``mcap``'s ``NonSeekingReader`` does); a file that ended
properly is kept as it is, a damaged one is rewritten with the same schemas,
channels, messages (same times, same order), attachments and ``rosbag2`` record,
then a summary. ``metadata.yaml`` is rebuilt from what the files hold.
"""

from __future__ import annotations

import logging
import os
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path

import zstandard
from mcap.exceptions import McapError
from mcap.records import Attachment, Channel, Footer, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter

from splitter_bag.core.metadata import (
    MCAP_METADATA_KEY,
    MCAP_METADATA_NAME,
    TIME_POINT_MAX_NS,
    BagMetadata,
    FileInformation,
    MetadataError,
    TopicInformation,
    TopicMetadata,
    parse_qos_profiles,
    parse_serialized_metadata,
    ros_distro,
    write_metadata,
)
from splitter_bag.core.reader import sorted_mcap_files
from splitter_bag.core.writer import LIBRARY, PROFILE

_log = logging.getLogger(__name__)

RECOVERY_CHUNK_SIZE_BYTES = 768 * 1024  # [B]


class RecoveryError(RuntimeError):
    """Nothing recoverable (no .mcap file, or a file that is not MCAP at all)."""


@dataclass
class FileRecovery:
    """What was found in one ``.mcap`` and what was done with it."""

    path: Path
    complete: bool  # ended with a footer: left untouched
    rewritten: bool = False
    message_count: int = 0
    error: str = ""  # why reading stopped early
    starting_time_ns: int = TIME_POINT_MAX_NS
    end_time_ns: int = 0
    counts: dict[str, int] = field(default_factory=dict)  # by topic


@dataclass
class RecoveryReport:
    bag_dir: Path
    files: list[FileRecovery]
    metadata: BagMetadata

    @property
    def message_count(self) -> int:
        return self.metadata.message_count

    def summary(self) -> str:
        lines = [f"recovered {self.bag_dir}: {self.message_count} messages"]
        for f in self.files:
            state = "complete" if f.complete else ("rewritten" if f.rewritten else "unchanged")
            extra = f" (read stopped: {f.error})" if f.error else ""
            lines.append(f"  {f.path.name}: {f.message_count} messages, {state}{extra}")
        return "\n".join(lines)


@dataclass
class _Scan:
    header: Header | None = None
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    messages: list[Message] = field(default_factory=list)
    rosbag2_records: list[str] = field(default_factory=list)
    attachments: list[Attachment] = field(default_factory=list)
    complete: bool = False
    error: str = ""


def _records(path: Path, scan: _Scan) -> Iterator[object]:
    with open(path, "rb") as f:
        reader = StreamReader(f, validate_crcs=True)
        try:
            yield from reader.records
        except (
            McapError,
            EOFError,
            ValueError,
            KeyError,
            struct.error,
            zstandard.ZstdError,
        ) as exc:
            # The torn end of a killed recording: a short read, a chunk whose CRC or
            # compression does not check out. Reading stops at the first record that is
            # not whole; the reason is reported, never ignored.
            scan.error = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__


def _scan(path: Path) -> _Scan:
    scan = _Scan()
    for record in _records(path, scan):
        if isinstance(record, Header):
            scan.header = record
        elif isinstance(record, Schema):
            scan.schemas[record.id] = record
        elif isinstance(record, Channel):
            scan.channels[record.id] = record
        elif isinstance(record, Message):
            if record.channel_id in scan.channels:
                scan.messages.append(record)
        elif isinstance(record, Metadata) and record.name == MCAP_METADATA_NAME:
            scan.rosbag2_records.append(record.metadata.get(MCAP_METADATA_KEY, ""))
        elif isinstance(record, Attachment):
            scan.attachments.append(record)
        elif isinstance(record, Footer):
            scan.complete = True
    if scan.header is None and not scan.error:
        scan.error = "no MCAP header"
    return scan


def _rewrite(path: Path, scan: _Scan, final_record: str) -> None:
    """Write ``scan`` as a complete MCAP next to ``path``, then replace ``path`` with it."""
    tmp = path.with_name(path.name + ".recovering")
    compression = CompressionType.ZSTD
    with open(tmp, "wb") as f:
        writer = McapWriter(f, chunk_size=RECOVERY_CHUNK_SIZE_BYTES, compression=compression)
        header = scan.header
        writer.start(
            profile=header.profile if header else PROFILE,
            library=header.library if header else LIBRARY,
        )
        if scan.rosbag2_records:
            writer.add_metadata(MCAP_METADATA_NAME, {MCAP_METADATA_KEY: scan.rosbag2_records[0]})
        for a in scan.attachments:  # e.g. the nodes' parameters
            writer.add_attachment(a.create_time, a.log_time, a.name, a.media_type, a.data)
        schema_ids = {
            old: writer.register_schema(s.name, s.encoding, s.data)
            for old, s in sorted(scan.schemas.items())
        }
        channel_ids = {
            old: writer.register_channel(
                c.topic, c.message_encoding, schema_ids.get(c.schema_id, 0), dict(c.metadata)
            )
            for old, c in sorted(scan.channels.items())
        }
        for m in scan.messages:
            writer.add_message(
                channel_ids[m.channel_id], m.log_time, m.data, m.publish_time, m.sequence
            )
        writer.add_metadata(MCAP_METADATA_NAME, {MCAP_METADATA_KEY: final_record})
        writer.finish()
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def _file_stats(path: Path, scan: _Scan) -> FileRecovery:
    rec = FileRecovery(path=path, complete=scan.complete, error=scan.error)
    rec.message_count = len(scan.messages)
    for m in scan.messages:
        topic = scan.channels[m.channel_id].topic
        rec.counts[topic] = rec.counts.get(topic, 0) + 1
        rec.starting_time_ns = min(rec.starting_time_ns, m.log_time)
        rec.end_time_ns = max(rec.end_time_ns, m.log_time)
    return rec


def recover_bag(bag_dir: Path | str) -> RecoveryReport:
    """Make ``bag_dir`` a complete, readable bag; returns what was recovered.

    Idempotent: on a complete bag no ``.mcap`` is touched and metadata.yaml is
    rewritten with the same content.
    """
    bag_dir = Path(bag_dir)
    paths = sorted_mcap_files(bag_dir)
    if not paths:
        raise RecoveryError(f"{bag_dir} holds no .mcap file")
    scans = []
    for path in paths:
        scan = _scan(path)
        if scan.header is None:
            raise RecoveryError(f"{path} is not an MCAP file ({scan.error})")
        scans.append(scan)

    files: list[FileRecovery] = [_file_stats(p, s) for p, s in zip(paths, scans, strict=True)]
    topics: dict[str, TopicMetadata] = {}
    for scan in scans:
        for c in scan.channels.values():
            if c.topic in topics:
                continue
            schema = scan.schemas.get(c.schema_id)
            topics[c.topic] = TopicMetadata(
                name=c.topic,
                type=schema.name if schema else "",
                serialization_format=c.message_encoding,
                offered_qos_profiles=tuple(
                    parse_qos_profiles(c.metadata.get("offered_qos_profiles"))
                ),
                type_description_hash=c.metadata.get("topic_type_hash", ""),
            )
    counts: dict[str, int] = {}
    for f in files:
        for topic, n in f.counts.items():
            counts[topic] = counts.get(topic, 0) + n
    base = _recorded_metadata(scans)
    file_infos = tuple(
        FileInformation(
            path=f.path.name,
            starting_time_ns=f.starting_time_ns,
            duration_ns=(f.end_time_ns - f.starting_time_ns) if f.message_count else 0,
            message_count=f.message_count,
        )
        for f in files
    )
    with_messages = [f for f in files if f.message_count]
    start = min((f.starting_time_ns for f in with_messages), default=TIME_POINT_MAX_NS)
    end = max((f.end_time_ns for f in with_messages), default=0)
    metadata = replace(
        base,
        relative_file_paths=tuple(f.path.name for f in files),
        files=file_infos,
        starting_time_ns=start,
        duration_ns=end - start if with_messages else 0,
        message_count=sum(counts.values()),
        topics_with_message_count=tuple(
            TopicInformation(t, counts.get(name, 0)) for name, t in sorted(topics.items())
        ),
    )
    for rec, scan in zip(files, scans, strict=True):
        if not rec.complete:
            _rewrite(rec.path, scan, metadata.serialized())
            rec.rewritten = True
            _log.info("rewrote %s with %d messages", rec.path.name, rec.message_count)
    write_metadata(bag_dir, metadata)
    return RecoveryReport(bag_dir=bag_dir, files=files, metadata=metadata)


def _recorded_metadata(scans: list[_Scan]) -> BagMetadata:
    """custom_data, ros_distro and compression fields from the first readable rosbag2 record."""
    for scan in scans:
        for text in scan.rosbag2_records:
            try:
                return parse_serialized_metadata(text)
            except MetadataError as exc:
                _log.warning("unreadable rosbag2 record: %s", exc)
    return BagMetadata(ros_distro=ros_distro())
