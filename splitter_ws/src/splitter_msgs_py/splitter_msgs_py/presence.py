"""Whether a topic has a publisher, asked thousands of times a run.

In lockstep the simulator asks, at every control tick, which command topics have a
publisher to wait for, and the MPC asks whether a gait manager will answer the
tick. ``Node.count_publishers`` queries the ROS graph each time (~30 us with its
topic-name expansion). :class:`PublisherPresence` remembers a publisher it found
for ``hold_s`` wall seconds; a topic without one is asked again every time, so a
publisher that joins is seen at once and one that leaves within ``hold_s``.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from rclpy.node import Node

PRESENCE_HOLD_S = 0.5  # [s] wall: how long a publisher found is trusted


class PublisherPresence:
    """``presence(topic)``: True when ``topic`` has a publisher (see the module)."""

    def __init__(
        self,
        node: Node,
        hold_s: float = PRESENCE_HOLD_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if not hold_s >= 0.0:
            raise ValueError(f"hold_s must be >= 0 s, got {hold_s!r}")
        self._node = node
        self._hold_s = float(hold_s)
        self._clock = clock
        self._seen_until: dict[str, float] = {}

    def __call__(self, topic: str) -> bool:
        now = self._clock()
        until = self._seen_until.get(topic)
        if until is not None and now < until:
            return True
        if self._node.count_publishers(topic) > 0:
            self._seen_until[topic] = now + self._hold_s
            return True
        self._seen_until.pop(topic, None)
        return False
