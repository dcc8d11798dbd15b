"""Node parameters described where they belong: on the fields of a core's config dataclass.

A core's config dataclass (``SimConfig``, ``AllocatorConfig``, ...) marks each
field a node exposes as a ROS parameter with :func:`parameter_field`: default,
description with unit, range, choices, and whether a runtime change is applied
live. The node declares its parameters from that one source
(:func:`splitter_msgs_py.parameters.specs_from_config`) and builds the config
from the values it read (:func:`splitter_msgs_py.parameters.config_from_values`),
so names, ranges and defaults are written once. ROS-free.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

PARAMETER_KEY = "splitter_parameter"


@dataclass(frozen=True)
class ParameterInfo:
    """What a node needs to declare a config field as a parameter (besides name, default)."""

    description: str
    min_value: float | None = None
    max_value: float | None = None
    choices: tuple[str, ...] | None = None
    length: int | None = None  # fixed size of an array
    item_type: type = float  # float or str, for tuple defaults
    live: bool = False


def parameter_field(
    default: Any,
    description: str,
    *,
    min_value: float | None = None,
    max_value: float | None = None,
    choices: tuple[str, ...] | None = None,
    length: int | None = None,
    item_type: type = float,
    live: bool = False,
) -> Any:
    """A dataclass field with ``default`` that a node exposes as a parameter.

    Array parameters have tuple defaults (a frozen dataclass's field must be immutable).
    """
    info = ParameterInfo(description, min_value, max_value, choices, length, item_type, live)
    return dataclasses.field(default=default, metadata={PARAMETER_KEY: info})


def parameter_fields(config_class: type) -> list[tuple[str, Any, ParameterInfo]]:
    """``(name, default, info)`` of every field of ``config_class`` marked as a parameter."""
    out = []
    for f in dataclasses.fields(config_class):
        info = f.metadata.get(PARAMETER_KEY)
        if info is not None:
            out.append((f.name, f.default, info))
    return out
