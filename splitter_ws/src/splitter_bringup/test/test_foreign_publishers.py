"""Publishers on the graph's topics that the graph did not start."""

from __future__ import annotations

from splitter_bringup.analysis.foreign_publishers import (
    UNKNOWN_NODE_NAME,
    UNKNOWN_NODE_NAMESPACE,
    ForeignPublisherTracker,
    qualified_name,
)

NAMELESS = qualified_name(UNKNOWN_NODE_NAMESPACE, UNKNOWN_NODE_NAME)


def test_unknown_nodes_and_second_publishers_of_a_graph_node_are_foreign_once() -> None:
    tracker = ForeignPublisherTracker(["simulator", "recorder"])
    ours = {"/splitter/imu": [("/simulator", b"a")], "/clock": [("/simulator", b"b")]}
    assert tracker.update(ours) == []
    assert tracker.update(ours) == []
    injected = {
        "/splitter/imu": [("/simulator", b"a"), ("/_ros2cli_42", b"c")],
        "/clock": [("/simulator", b"b"), ("/simulator", b"d")],  # another graph's simulator
    }
    found = tracker.update(injected)
    assert [(f.topic, f.node) for f in found] == [
        ("/splitter/imu", "/_ros2cli_42"),
        ("/clock", "/simulator"),
    ]
    assert "another graph" in found[1].reason
    assert found[0].line().startswith("FOREIGN publisher /_ros2cli_42 on /splitter/imu: ")
    assert tracker.update(injected) == []  # each reported once
    assert tracker.count == 2


def test_qualified_names() -> None:
    assert qualified_name("/", "simulator") == "/simulator"
    assert qualified_name("/robot", "simulator") == "/robot/simulator"


def test_an_endpoint_discovery_has_not_named_yet_is_ours_once_named() -> None:
    tracker = ForeignPublisherTracker(["simulator"], unknown_grace_updates=2)
    assert tracker.update({"/clock": [(NAMELESS, b"a")]}) == []
    assert tracker.update({"/clock": [(NAMELESS, b"a")]}) == []
    assert tracker.update({"/clock": [("/simulator", b"a")]}) == []
    assert tracker.count == 0


def test_an_endpoint_that_stays_nameless_is_foreign_after_the_grace() -> None:
    tracker = ForeignPublisherTracker(["simulator"], unknown_grace_updates=2)
    seen = {"/clock": [("/simulator", b"a"), (NAMELESS, b"z")]}
    assert tracker.update(seen) == []
    assert tracker.update(seen) == []
    found = tracker.update(seen)
    assert [(f.topic, f.node) for f in found] == [("/clock", NAMELESS)]
    assert "no ROS node owns it" in found[0].reason
    assert tracker.update(seen) == []
    assert tracker.count == 1
