"""Look into messages and what a node publishes: for tests and graph checks.

* :func:`non_finite_fields`: every NaN or infinity in a message, nested messages,
  sequences and the numeric values of ``diagnostic_msgs/KeyValue`` included.
* :func:`record_publications`: every message a node publishes, by topic, while its
  publishers keep publishing.
"""

from __future__ import annotations

import array
import math
from collections import defaultdict

import numpy as np
from rclpy.node import Node


def non_finite_fields(value: object, path: str = "msg") -> list[str]:
    """Paths of the NaN and infinite numbers in ``value`` (a message, sequence or number)."""
    if hasattr(value, "get_fields_and_field_types"):
        out = []
        for field in value.get_fields_and_field_types():
            out += non_finite_fields(getattr(value, field), f"{path}.{field}")
        return out
    if isinstance(value, float):
        return [] if math.isfinite(value) else [path]
    if isinstance(value, list | tuple | array.array | np.ndarray):
        out = []
        for i, item in enumerate(value):
            out += non_finite_fields(item, f"{path}[{i}]")
        return out
    if isinstance(value, str) and path.endswith(".value"):  # diagnostics KeyValue
        try:
            number = float(value)
        except ValueError:
            return []
        return [] if math.isfinite(number) else [f"{path} = {value}"]
    return []


def record_publications(node: Node) -> dict[str, list]:
    """Every message ``node`` publishes from now on, by topic (its publishers still publish)."""
    out: dict[str, list] = defaultdict(list)
    for publisher in node.publishers:
        original = publisher.publish

        def publish(msg, topic=publisher.topic_name, original=original) -> None:
            out[topic].append(msg)
            original(msg)

        publisher.publish = publish
    return out
