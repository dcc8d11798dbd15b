"""Publishers on the graph's topics that the graph did not start."""

from __future__ import annotations

from splitter_bringup.analysis.foreign_publishers import ForeignPublisherTracker, qualified_name


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
