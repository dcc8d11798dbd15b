"""non_finite_fields finds every NaN and infinity; record_publications keeps what a node sends."""

from __future__ import annotations

import math

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from splitter_msgs_py.inspection import non_finite_fields, record_publications


def test_nested_fields_sequences_and_diagnostic_values_are_searched() -> None:
    joints = JointState(position=[0.0, math.nan], velocity=[math.inf])
    joints.header.stamp.sec = 1
    assert non_finite_fields(joints) == ["msg.position[1]", "msg.velocity[0]"]
    status = DiagnosticStatus(
        values=[KeyValue(key="a", value="1.5"), KeyValue(key="b", value="-inf")]
    )
    found = non_finite_fields(DiagnosticArray(status=[status]))
    assert found == ["msg.status[0].values[1].value = -inf"]
    assert non_finite_fields(JointState(position=[1.0], name=["nan"])) == []  # names are text


def test_record_publications_keeps_and_still_publishes(ros_context) -> None:
    from rclpy.node import Node

    node = Node("inspection_probe", context=ros_context)
    try:
        publisher = node.create_publisher(String, "/inspection_probe", 1)
        published = record_publications(node)
        publisher.publish(String(data="x"))
        assert [m.data for m in published["/inspection_probe"]] == ["x"]
    finally:
        node.destroy_node()
