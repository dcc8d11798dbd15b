"""String-list node parameters of the recorder and player (imports rclpy).

:mod:`splitter_msgs_py.parameters` has no string arrays; a topic list arrives
either as a YAML list (parameter files, in-process overrides) or as one string
(``-p topics:=/a,/b`` on a command line), so both are accepted and validated here.
"""

from __future__ import annotations

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node

from splitter_bag.core.playback import parse_topic_list
from splitter_msgs_py.parameters import READ_ONLY_NOTE, InvalidParameterError


def declare_string_list(node: Node, name: str, description: str) -> list[str]:
    """Declare ``name`` (a list of strings, or one comma/space separated string) and read it."""
    descriptor = ParameterDescriptor(
        name=name,
        description=description + " (list, or one comma separated string)" + READ_ONLY_NOTE,
        read_only=True,
    )
    descriptor.dynamic_typing = True
    node.declare_parameter(name, "", descriptor)
    value = node.get_parameter(name).value
    if value is None:
        return []
    if isinstance(value, str):
        return parse_topic_list(value)
    if isinstance(value, list | tuple) and all(isinstance(v, str) for v in value):
        return [v.strip() for v in value if v.strip()]
    raise InvalidParameterError(f"parameter '{name}' must be a list of strings, got {value!r}")


def declare_topic_list(node: Node, name: str, description: str) -> list[str]:
    """A list of absolute topic names (a name without a leading '/' is taken as absolute)."""
    topics = declare_string_list(node, name, description)
    out = []
    for topic in topics:
        full = topic if topic.startswith("/") else "/" + topic
        if "//" in full or full.endswith("/") or any(c.isspace() for c in full):
            raise InvalidParameterError(f"parameter '{name}': {topic!r} is not a topic name")
        out.append(full)
    return out


def declare_key_values(node: Node, name: str, description: str) -> dict[str, str]:
    """``KEY=VALUE`` items (a list, or one string separated by ',' or ';')."""
    descriptor = ParameterDescriptor(
        name=name, description=description + READ_ONLY_NOTE, read_only=True
    )
    descriptor.dynamic_typing = True
    node.declare_parameter(name, "", descriptor)
    value = node.get_parameter(name).value
    if isinstance(value, str):
        items = [v for v in value.replace(";", ",").split(",") if v.strip()]
    elif isinstance(value, list | tuple) and all(isinstance(v, str) for v in value):
        items = list(value)
    else:
        raise InvalidParameterError(f"parameter '{name}' must be KEY=VALUE strings, got {value!r}")
    out = {}
    for item in items:
        key, sep, val = item.partition("=")
        if not sep or not key.strip():
            raise InvalidParameterError(f"parameter '{name}': {item!r} is not KEY=VALUE")
        out[key.strip()] = val.strip()
    return out
