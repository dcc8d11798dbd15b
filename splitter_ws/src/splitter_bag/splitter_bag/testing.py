"""Helpers for the bag tests (ROS-free).

:func:`complete_chunk_messages` reads a torn MCAP file with the ``mcap`` stream
reader alone, independent of :func:`splitter_bag.recover_bag`, so a test can say
what recovery must give back.
"""

from __future__ import annotations

import struct
from pathlib import Path

from mcap.exceptions import EndOfFile
from mcap.records import Chunk, Message
from mcap.stream_reader import StreamReader, breakup_chunk


def complete_chunk_messages(path: Path) -> list[Message]:
    """The messages of the chunks that are whole in ``path`` (a torn end is skipped)."""
    out: list[Message] = []
    with open(path, "rb") as f:
        try:
            for record in StreamReader(f, emit_chunks=True).records:
                if isinstance(record, Chunk):
                    out.extend(r for r in breakup_chunk(record) if isinstance(r, Message))
        except (EndOfFile, struct.error):  # the torn end, inside a record or its length
            pass
    return out
