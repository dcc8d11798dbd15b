"""PublisherPresence: a publisher found is trusted for hold_s, an absent one asked again."""

from __future__ import annotations

import pytest

from splitter_msgs_py.presence import PublisherPresence


class GraphOf:
    """Stands in for a node's graph: publisher counts per topic, and how often asked."""

    def __init__(self) -> None:
        self.publishers: dict[str, int] = {}
        self.queries = 0

    def count_publishers(self, topic: str) -> int:
        self.queries += 1
        return self.publishers.get(topic, 0)


def test_a_found_publisher_is_trusted_for_hold_s_and_an_absent_one_asked_every_time() -> None:
    graph, now = GraphOf(), [100.0]
    presence = PublisherPresence(graph, hold_s=0.5, clock=lambda: now[0])
    assert not presence("/a") and not presence("/a")
    assert graph.queries == 2  # no publisher: asked each time
    graph.publishers["/a"] = 1
    assert presence("/a")  # a publisher that joins is seen at once
    assert graph.queries == 3
    graph.publishers["/a"] = 0  # it leaves ...
    now[0] += 0.49
    assert presence("/a")  # ... trusted within hold_s, without asking
    assert graph.queries == 3
    now[0] += 0.02
    assert not presence("/a")  # ... and seen gone after it
    assert graph.queries == 4


def test_hold_s_must_not_be_negative() -> None:
    with pytest.raises(ValueError, match="hold_s"):
        PublisherPresence(GraphOf(), hold_s=-1.0)
    with pytest.raises(ValueError, match="hold_s"):
        PublisherPresence(GraphOf(), hold_s=float("nan"))
