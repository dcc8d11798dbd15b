"""A node's ``/diagnostics`` status: its core's content plus what every node reports.

A node's ROS-free core gives the level, message and values of its status; the node
adds the inputs it rejected (:func:`~splitter_msgs_py.parameters.rejection_counts`)
and its live parameter changes (:func:`~splitter_msgs_py.parameters.parameter_diagnostics`)
and publishes it stamped with the tick it describes.
"""

from __future__ import annotations

from collections.abc import Mapping

from rclpy.node import Node
from rclpy.publisher import Publisher

from splitter_msgs_py.conversions import DiagnosticStatusSample, diagnostics_to_msg
from splitter_msgs_py.core.stamps import MessageValidationError
from splitter_msgs_py.parameters import parameter_diagnostics, rejection_counts


def publish_status(
    node: Node,
    publisher: Publisher,
    t_ns: int,
    name: str,
    status: tuple[int, str, Mapping[str, float | int | str | bool]],
) -> None:
    """Publish ``status`` = (level, message, values) as ``name`` stamped ``t_ns``.

    The values get ``rejected_messages`` and the parameter changes; a status the
    message cannot carry is logged as an error, not published.
    """
    level, message, values = status
    values = {
        **values,
        "rejected_messages": sum(rejection_counts(node).values()),
        **parameter_diagnostics(node),
    }
    sample = DiagnosticStatusSample(name, level, message, values)
    try:
        publisher.publish(diagnostics_to_msg(t_ns, [sample]))
    except MessageValidationError as exc:
        node.get_logger().error(f"diagnostics not published: {exc}")
