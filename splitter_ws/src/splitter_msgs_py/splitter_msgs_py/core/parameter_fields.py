"""Node parameters described where they belong: on the fields of a core's config dataclass.

A core's config dataclass (``SimConfig``, ``AllocatorConfig``, ...) marks each
field a node exposes as a ROS parameter with :func:`parameter_field`: default,
description with unit, range, choices, and whether a runtime change is applied
live. The node declares its parameters from that one source
(:func:`splitter_msgs_py.parameters.specs_from_config`) and builds the config
from the values it read (:func:`splitter_msgs_py.parameters.config_from_values`),
so names, ranges and defaults are written once. A :class:`ParameterSpec` also
validates a value (type, finiteness, range, choices, length). ROS-free.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

PARAMETER_KEY = "splitter_parameter"

ParameterValue = bool | int | float | str | list[float] | list[str]

# Ranges ``(lowest, highest)`` shared by parameters of one kind.
FRACTION = (1e-3, 1.0)  # [-] a share of a limit (zero would stop what it limits)
PERIOD_S = (1e-3, 10.0)  # [s] a node's periodic work (re-plan, diagnostics) in simulated time


class InvalidParameterError(ValueError):
    """A node parameter whose value is out of range, non-finite or of the wrong shape."""


@dataclass(frozen=True)
class ParameterSpec:
    """One node parameter: the default's type decides the ROS type.

    A list default is a float array, or a string array with ``item_type=str``
    (needed because an empty default says nothing about its items). ``live``:
    a runtime change is validated and applied
    (:mod:`splitter_msgs_py.parameters`); otherwise the parameter is read-only.
    """

    name: str
    default: ParameterValue
    description: str
    min_value: float | None = None
    max_value: float | None = None
    choices: tuple[str, ...] | None = None
    length: int | None = None  # fixed size of an array
    item_type: type = float  # float or str, for list defaults
    live: bool = False

    @property
    def is_float(self) -> bool:
        """A float number or a float array (an integer given for it is accepted)."""
        if isinstance(self.default, list):
            return self.item_type is not str
        return isinstance(self.default, float)

    def validate(self, value: object) -> ParameterValue:
        """The value, checked against type, finiteness, range, choices and length."""
        where = f"parameter '{self.name}'"
        if isinstance(self.default, bool):
            if not isinstance(value, bool):
                raise InvalidParameterError(f"{where} must be a bool, got {value!r}")
            return value
        if isinstance(self.default, str):
            if not isinstance(value, str):
                raise InvalidParameterError(f"{where} must be a string, got {value!r}")
            if self.choices and value not in self.choices:
                raise InvalidParameterError(f"{where} must be one of {self.choices}, got {value!r}")
            return value
        if isinstance(self.default, list) and self.item_type is str:
            if not isinstance(value, list | tuple) or not all(isinstance(v, str) for v in value):
                raise InvalidParameterError(f"{where} must be a list of strings, got {value!r}")
            if self.choices and any(v not in self.choices for v in value):
                raise InvalidParameterError(f"{where} items must be in {self.choices}")
            return list(value)
        if isinstance(self.default, list):
            items = None if isinstance(value, str | bytes) else value
            try:
                if any(isinstance(v, bool) for v in items):  # type: ignore[union-attr]
                    raise TypeError("bool items")
                values = [float(v) for v in items]  # type: ignore[union-attr]
            except (TypeError, ValueError):
                raise InvalidParameterError(
                    f"{where} must be a list of numbers, got {value!r}"
                ) from None
            if self.length is not None and len(values) != self.length:
                raise InvalidParameterError(
                    f"{where} must have {self.length} values, got {len(values)}"
                )
            for v in values:
                self._check_number(v, where)
            return values
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise InvalidParameterError(f"{where} must be a number, got {value!r}")
        if isinstance(self.default, int):
            if isinstance(value, float) and not (math.isfinite(value) and value.is_integer()):
                raise InvalidParameterError(f"{where} must be an integer, got {value!r}")
            number: int | float = int(value)
        else:
            number = float(value)
        self._check_number(float(number), where)
        return number

    def _check_number(self, v: float, where: str) -> None:
        if not math.isfinite(v):
            raise InvalidParameterError(f"{where} must be finite, got {v}")
        if self.min_value is not None and v < self.min_value:
            raise InvalidParameterError(f"{where} must be >= {self.min_value}, got {v}")
        if self.max_value is not None and v > self.max_value:
            raise InvalidParameterError(f"{where} must be <= {self.max_value}, got {v}")


def parameter_field(
    default: Any,
    description: str,
    *,
    bounds: tuple[float, float] | None = None,
    min_value: float | None = None,
    max_value: float | None = None,
    choices: tuple[str, ...] | None = None,
    length: int | None = None,
    item_type: type = float,
    live: bool = False,
) -> Any:
    """A dataclass field with ``default`` that a node exposes as a parameter.

    ``bounds``: the range ``(min_value, max_value)`` in one argument (a named one
    such as :data:`FRACTION`, or a literal); ``min_value`` alone leaves the top
    open. Array parameters have tuple defaults (a frozen dataclass's field must be
    immutable). The field's metadata holds the parameter's :class:`ParameterSpec`,
    named by :func:`parameter_fields`.
    """
    if bounds is not None:
        if min_value is not None or max_value is not None:
            raise TypeError("give bounds or min_value / max_value, not both")
        min_value, max_value = bounds
    spec = ParameterSpec(
        name="",
        default=list(default) if isinstance(default, tuple) else default,
        description=description,
        min_value=min_value,
        max_value=max_value,
        choices=choices,
        length=length,
        item_type=item_type,
        live=live,
    )
    return dataclasses.field(default=default, metadata={PARAMETER_KEY: spec})


def parameter_fields(config_class: type) -> list[tuple[str, Any, ParameterSpec]]:
    """``(name, default, spec)`` of every field of ``config_class`` marked as a parameter."""
    out = []
    for f in dataclasses.fields(config_class):
        spec = f.metadata.get(PARAMETER_KEY)
        if spec is not None:
            out.append((f.name, f.default, dataclasses.replace(spec, name=f.name)))
    return out
