"""Playback timing and topic selection of a bag player (ROS-free, pure).

A player maps bag time (log time, what rosbag2 plays on) onto a monotonic wall
clock: ``wall = wall_start + (bag - bag_start) / rate``.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass

_NS_PER_S = 1_000_000_000


@dataclass(frozen=True)
class PlaybackClock:
    """Affine map between bag time and wall time for a rate factor."""

    bag_start_ns: int  # [ns] bag time played at wall_start_ns
    wall_start_ns: int  # [ns] monotonic wall time
    rate: float = 1.0  # bag seconds per wall second

    def __post_init__(self) -> None:
        if not self.rate > 0.0:
            raise ValueError(f"rate must be > 0, got {self.rate}")

    def wall_time_ns(self, bag_time_ns: int) -> int:
        """When (monotonic wall time) a message logged at ``bag_time_ns`` is due."""
        return self.wall_start_ns + round((bag_time_ns - self.bag_start_ns) / self.rate)

    def bag_time_ns(self, wall_time_ns: int) -> int:
        """The bag time being played at ``wall_time_ns``."""
        return self.bag_start_ns + round((wall_time_ns - self.wall_start_ns) * self.rate)


def parse_topic_list(text: str) -> list[str]:
    """Topics from a comma- or whitespace-separated string ("" = none given)."""
    return [t for t in re.split(r"[,\s]+", text.strip()) if t]


def select_topics(
    available: Iterable[str],
    topics: Iterable[str] = (),
    regex: str = "",
    exclude_regex: str = "",
) -> list[str]:
    """The topics chosen: listed ones and/or those matching ``regex`` (all if neither given).

    ``exclude_regex`` removes topics afterwards. Regexes match the whole name with
    ``re.search`` semantics like ``ros2 bag record --regex``.
    """
    listed = set(topics)
    pattern = re.compile(regex) if regex else None
    exclude = re.compile(exclude_regex) if exclude_regex else None
    chosen = []
    for name in sorted(set(available)):
        take = (not listed and pattern is None) or name in listed
        take = take or (pattern is not None and pattern.search(name) is not None)
        if take and not (exclude is not None and exclude.search(name)):
            chosen.append(name)
    return chosen


def seconds_to_ns(seconds: float) -> int:
    return round(seconds * _NS_PER_S)
