"""Write a rosbag2 bag directory as rosbag2_storage_mcap (Jazzy) writes it.

ROS-free: the writer takes serialized CDR bytes and times in nanoseconds, so a
recorder needs no deserialization (DESIGN.md section 9).

Layout, after rosbag2_cpp ``SequentialWriter`` and rosbag2_storage_mcap:

* ``<dir>/<basename(dir)>_<n>.mcap``: profile ``ros2``; one schema per type (name
  ``pkg/msg/Type``, encoding ``ros2msg``, the concatenated definition); one channel
  per topic (encoding ``cdr``, metadata ``offered_qos_profiles`` and
  ``topic_type_hash``); message ``sequence`` 0, ``log_time`` = receive time,
  ``publish_time`` = source time; a ``rosbag2`` metadata record with the bag's
  ``serialized_metadata`` when a file is opened and again before it is closed.
* ``<dir>/metadata.yaml`` (version 9) on close.
* Split when the bytes written to the current file reach ``max_bagfile_size_bytes``
  or the current file spans more than ``max_bagfile_duration_ns`` of log time.

Crash safety: chunks are closed by this class (at ``chunk_size_bytes`` of message
records, or ``flush_period_s`` after the chunk's first message) and every closed
chunk is handed to the operating system at once, so a process killed with SIGKILL
loses at most the chunk it was filling; :func:`splitter_bag.core.recover.recover_bag`
turns what is left into a complete bag.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import TracebackType
from typing import BinaryIO

import mcap
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter

from splitter_bag.core import definitions
from splitter_bag.core.metadata import (
    MCAP_METADATA_KEY,
    MCAP_METADATA_NAME,
    TIME_POINT_MAX_NS,
    BagMetadata,
    FileInformation,
    QosProfile,
    TopicInformation,
    TopicMetadata,
    ros_distro,
    serialize_qos_profiles,
    write_metadata,
)

_log = logging.getLogger(__name__)

PROFILE = "ros2"
MESSAGE_ENCODING = "cdr"
LIBRARY = f"splitter_msgs_py bag writer; mcap-python/{mcap.__version__}"
MESSAGE_RECORD_OVERHEAD_BYTES = 31  # opcode, length, channel, sequence, log and publish time
MINIMUM_SPLIT_FILE_SIZE_BYTES = 1024  # rosbag2_storage_mcap get_minimum_split_file_size()
COMPRESSIONS = {"zstd": CompressionType.ZSTD, "none": CompressionType.NONE}  # no lz4 wheel pinned


class BagWriterError(RuntimeError):
    """Misuse of a bag writer (closed, unknown topic, existing directory)."""


@dataclass(frozen=True)
class WriterOptions:
    """Storage options; defaults follow rosbag2_storage_mcap with chunk compression on."""

    chunk_size_bytes: int = 768 * 1024  # [B] libmcap's default chunk size
    compression: str = "zstd"  # "zstd" or "none" (chunk compression)
    flush_period_s: float = 1.0  # [s] wall time a chunk stays open at most
    max_bagfile_size_bytes: int = 0  # [B] split threshold, 0 = never
    max_bagfile_duration_ns: int = 0  # [ns] of log time per file, 0 = never
    custom_data: Mapping[str, str] = field(default_factory=dict)
    ros_distro: str = field(default_factory=ros_distro)

    def __post_init__(self) -> None:
        if self.chunk_size_bytes < 1:
            raise ValueError(f"chunk_size_bytes must be >= 1, got {self.chunk_size_bytes}")
        if self.compression not in COMPRESSIONS:
            raise ValueError(f"compression must be one of {sorted(COMPRESSIONS)}")
        if not self.flush_period_s > 0.0:
            raise ValueError(f"flush_period_s must be > 0, got {self.flush_period_s}")
        if 0 < self.max_bagfile_size_bytes < MINIMUM_SPLIT_FILE_SIZE_BYTES:
            raise ValueError(
                f"max_bagfile_size_bytes must be 0 or >= {MINIMUM_SPLIT_FILE_SIZE_BYTES}"
                f" (rosbag2_storage_mcap's minimum), got {self.max_bagfile_size_bytes}"
            )
        if self.max_bagfile_duration_ns < 0:
            raise ValueError("max_bagfile_duration_ns must be >= 0")


def bag_file_name(bag_dir: Path, index: int) -> str:
    """``<basename>_<index>.mcap``, rosbag2's ``format_storage_uri`` plus the extension."""
    return f"{bag_dir.name}_{index}.mcap"


@dataclass
class _Topic:
    metadata: TopicMetadata
    definition: definitions.MessageDefinition
    channel_id: int = 0
    message_count: int = 0


class _McapFile:
    """One open ``.mcap`` of the bag with the chunking done here (see module doc)."""

    def __init__(self, path: Path, options: WriterOptions) -> None:
        self.path = path
        self._stream: BinaryIO = open(path, "xb")  # closed in close()
        # The library never closes a chunk itself: this class does, then flushes.
        self.mcap = McapWriter(
            self._stream,
            chunk_size=2**62,
            compression=COMPRESSIONS[options.compression],
        )
        self.mcap.start(profile=PROFILE, library=LIBRARY)
        self.schema_ids: dict[str, int] = {}
        self.pending_bytes = 0  # [B] message records in the open chunk
        self.chunk_opened_at = 0.0  # [s] monotonic time of the open chunk's first message
        self.starting_time_ns = TIME_POINT_MAX_NS
        self.duration_ns = 0
        self.message_count = 0

    def bytes_written(self) -> int:
        """Bytes handed to the file so far (the open chunk excluded), like libmcap's data sink."""
        return self._stream.tell()

    def close_chunk(self) -> None:
        if self.pending_bytes:
            self.mcap.flush()  # closes the chunk, writes it and its index, flushes the stream
            self.pending_bytes = 0

    def close(self) -> None:
        try:
            self.mcap.finish()
            self._stream.flush()
            os.fsync(self._stream.fileno())
        finally:
            self._stream.close()


class BagWriter:
    """A rosbag2 MCAP bag being written (context manager; close() is idempotent).

    ``with BagWriter(dir) as bag: bag.add_topic(...); bag.write(topic, cdr, log_ns, pub_ns)``.
    """

    def __init__(self, bag_dir: Path | str, options: WriterOptions | None = None) -> None:
        self.bag_dir = Path(bag_dir)
        self.options = options or WriterOptions()
        if self.bag_dir.exists():
            raise BagWriterError(f"bag directory {self.bag_dir} already exists, can't overwrite")
        self.bag_dir.mkdir(parents=True)
        self._topics: dict[str, _Topic] = {}
        self._files: list[FileInformation] = []
        self._starting_time_ns = TIME_POINT_MAX_NS
        self._duration_ns = 0
        self._closed = False
        self._file: _McapFile | None = None
        self._file = self._open_file(0)

    # -- context manager ----------------------------------------------------------
    def __enter__(self) -> BagWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    # -- public API ---------------------------------------------------------------
    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def topics(self) -> dict[str, TopicMetadata]:
        return {name: t.metadata for name, t in self._topics.items()}

    @property
    def message_counts(self) -> dict[str, int]:
        return {name: t.message_count for name, t in self._topics.items()}

    @property
    def current_file(self) -> Path:
        return self._require_file().path

    def has_topic(self, name: str) -> bool:
        return name in self._topics

    def add_topic(
        self,
        name: str,
        type_name: str,
        offered_qos_profiles: Sequence[QosProfile] = (),
        type_description_hash: str | None = None,
        serialization_format: str = MESSAGE_ENCODING,
    ) -> TopicMetadata:
        """Register a topic (idempotent): schema and channel of the current file.

        The definition is looked up in the installed interfaces; the type hash too
        when not given (a recorder passes the one its publishers advertise).
        """
        self._check_open()
        if name in self._topics:
            return self._topics[name].metadata
        if type_description_hash is None:
            type_description_hash = definitions.type_description_hash(type_name)
        metadata = TopicMetadata(
            name=name,
            type=type_name,
            serialization_format=serialization_format,
            offered_qos_profiles=tuple(offered_qos_profiles),
            type_description_hash=type_description_hash,
        )
        topic = _Topic(metadata, definitions.message_definition(type_name))
        self._register(self._require_file(), topic)
        self._topics[name] = topic
        return metadata

    def write(self, topic: str, data: bytes, log_time_ns: int, publish_time_ns: int) -> None:
        """Append one serialized message (``log_time_ns`` orders the bag)."""
        if self._closed:
            raise BagWriterError("bag writer is closed")
        try:
            entry = self._topics[topic]
        except KeyError:
            raise BagWriterError(f"topic {topic!r} was not added before writing") from None
        if log_time_ns < 0 or publish_time_ns < 0:
            raise ValueError(f"negative time on {topic}: {log_time_ns}, {publish_time_ns}")
        f = self._require_file()
        if self._should_split(f, log_time_ns):
            f = self._split()
        now = time.monotonic()
        if f.pending_bytes == 0:
            f.chunk_opened_at = now
        f.mcap.add_message(entry.channel_id, log_time_ns, data, publish_time_ns, 0)
        f.pending_bytes += MESSAGE_RECORD_OVERHEAD_BYTES + len(data)
        entry.message_count += 1
        f.message_count += 1
        f.starting_time_ns = min(f.starting_time_ns, log_time_ns)
        f.duration_ns = max(f.duration_ns, log_time_ns - f.starting_time_ns)
        self._starting_time_ns = min(self._starting_time_ns, log_time_ns)
        self._duration_ns = max(self._duration_ns, log_time_ns - self._starting_time_ns)
        if (
            f.pending_bytes >= self.options.chunk_size_bytes
            or now - f.chunk_opened_at >= self.options.flush_period_s
        ):
            f.close_chunk()

    def add_attachment(self, name: str, data: bytes, media_type: str, log_time_ns: int = 0) -> None:
        """Store a file in the current ``.mcap`` as an MCAP attachment (e.g. parameters).

        rosbag2 ignores attachments; ``mcap list attachments`` / ``mcap get attachment``
        and :func:`splitter_bag.core.reader.read_attachments` read them back.
        """
        self._check_open()
        f = self._require_file()
        f.close_chunk()  # an attachment goes between chunks
        f.mcap.add_attachment(time.time_ns(), log_time_ns, name, media_type, data)

    def flush(self) -> None:
        """Close the open chunk and hand it to the operating system."""
        if self._file is not None:
            self._file.close_chunk()

    def flush_if_due(self) -> None:
        """Close the open chunk if it has been open for ``flush_period_s`` (for idle timers)."""
        f = self._file
        if f is not None and f.pending_bytes:
            if time.monotonic() - f.chunk_opened_at >= self.options.flush_period_s:
                f.close_chunk()

    def split(self) -> Path:
        """Close the current file and continue in the next one; returns the new path."""
        self._check_open()
        return self._split().path

    def metadata(self) -> BagMetadata:
        """The bag's metadata as it stands (what close() writes)."""
        files = list(self._files)
        if self._file is not None:
            files.append(self._file_info(self._file))
        topics = tuple(
            TopicInformation(t.metadata, t.message_count) for _, t in sorted(self._topics.items())
        )
        return BagMetadata(
            relative_file_paths=tuple(f.path for f in files),
            files=tuple(files),
            duration_ns=self._duration_ns,
            starting_time_ns=self._starting_time_ns,
            message_count=sum(t.message_count for t in topics),
            topics_with_message_count=topics,
            custom_data=dict(self.options.custom_data),
            ros_distro=self.options.ros_distro,
        )

    def close(self) -> BagMetadata | None:
        """Finish the current file (summary, final ``rosbag2`` record) and write metadata.yaml."""
        if self._closed:
            return None
        f = self._require_file()
        try:
            self._write_rosbag2_record(f)
            f.close()
        finally:
            self._files.append(self._file_info(f))
            self._file = None
            self._closed = True
        metadata = self.metadata()
        write_metadata(self.bag_dir, metadata)
        return metadata

    # -- internals ------------------------------------------------------------------
    def _check_open(self) -> None:
        if self._closed:
            raise BagWriterError("bag writer is closed")

    def _require_file(self) -> _McapFile:
        if self._file is None:
            raise BagWriterError("bag writer is closed")
        return self._file

    def _file_info(self, f: _McapFile) -> FileInformation:
        return FileInformation(
            path=f.path.name,
            starting_time_ns=f.starting_time_ns,
            duration_ns=f.duration_ns,
            message_count=f.message_count,
        )

    def _open_file(self, index: int) -> _McapFile:
        f = _McapFile(self.bag_dir / bag_file_name(self.bag_dir, index), self.options)
        # rosbag2 records the metadata on opening a file: the first file lists itself,
        # a file opened by a split lists the files before it (SequentialWriter order).
        self._write_rosbag2_record(f, list_file=index == 0)
        return f

    def _write_rosbag2_record(self, f: _McapFile, list_file: bool = False) -> None:
        metadata = self.metadata()
        if list_file:
            metadata = replace(
                metadata,
                relative_file_paths=(*metadata.relative_file_paths, f.path.name),
                files=(*metadata.files, self._file_info(f)),
            )
        f.mcap.add_metadata(MCAP_METADATA_NAME, {MCAP_METADATA_KEY: metadata.serialized()})

    def _register(self, f: _McapFile, topic: _Topic) -> None:
        d = topic.definition
        schema_id = f.schema_ids.get(topic.metadata.type)
        if schema_id is None:
            schema_id = f.mcap.register_schema(
                name=topic.metadata.type,
                encoding=d.encoding,
                data=d.encoded_message_definition.encode("utf-8"),
            )
            f.schema_ids[topic.metadata.type] = schema_id
        topic.channel_id = f.mcap.register_channel(
            topic=topic.metadata.name,
            message_encoding=topic.metadata.serialization_format,
            schema_id=schema_id,
            metadata={
                "offered_qos_profiles": serialize_qos_profiles(topic.metadata.offered_qos_profiles),
                "topic_type_hash": topic.metadata.type_description_hash,
            },
        )

    def _should_split(self, f: _McapFile, log_time_ns: int) -> bool:
        if f.message_count == 0:
            return False
        opts = self.options
        if opts.max_bagfile_size_bytes and f.bytes_written() >= opts.max_bagfile_size_bytes:
            return True
        return bool(
            opts.max_bagfile_duration_ns
            and log_time_ns - f.starting_time_ns > opts.max_bagfile_duration_ns
        )

    def _split(self) -> _McapFile:
        old = self._require_file()
        self._write_rosbag2_record(old)
        old.close()
        self._files.append(self._file_info(old))
        self._file = None
        new = self._open_file(len(self._files))
        for topic in self._topics.values():
            self._register(new, topic)
        self._file = new
        _log.info("bag split: %s closed, %s opened", old.path.name, new.path.name)
        return new
