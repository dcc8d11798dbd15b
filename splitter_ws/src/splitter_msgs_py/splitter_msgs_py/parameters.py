"""Declared, described and validated node parameters, and throttled input warnings.

A node lists its parameters as :class:`ParameterSpec` objects and calls
:func:`declare_parameters` in ``__init__``: each is declared with a
``ParameterDescriptor`` (description, range) and its value validated; an
invalid value raises :class:`InvalidParameterError` naming the parameter, which
stops the node at start-up with that message.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.exceptions import ParameterException
from rclpy.node import Node

ParameterValue = bool | int | float | str | list[float] | list[str]


class InvalidParameterError(ValueError):
    """A node parameter whose value is out of range, non-finite or of the wrong shape."""


@dataclass(frozen=True)
class ParameterSpec:
    """One node parameter: the default's type decides the ROS type.

    A list default is a float array, or a string array with ``item_type=str``
    (needed because an empty default says nothing about its items).
    """

    name: str
    default: ParameterValue
    description: str
    min_value: float | None = None
    max_value: float | None = None
    choices: tuple[str, ...] | None = None
    length: int | None = None  # fixed size of an array
    item_type: type = float  # float or str, for list defaults

    def descriptor(self) -> ParameterDescriptor:
        """The ROS descriptor advertising description and range."""
        text = self.description
        if self.choices:
            text += f" (one of: {', '.join(self.choices)})"
        if self.length is not None:
            text += f" ({self.length} values)"
        desc = ParameterDescriptor(name=self.name, description=text)
        lo, hi = self.min_value, self.max_value
        if isinstance(self.default, bool) or (lo is None and hi is None):
            return desc
        if isinstance(self.default, int) and self.length is None:
            desc.integer_range = [
                IntegerRange(
                    from_value=int(lo if lo is not None else -(2**31)),
                    to_value=int(hi if hi is not None else 2**31 - 1),
                    step=0,
                )
            ]
        elif isinstance(self.default, float) and self.length is None:
            desc.floating_point_range = [
                FloatingPointRange(
                    from_value=float(lo if lo is not None else -math.inf),
                    to_value=float(hi if hi is not None else math.inf),
                    step=0.0,
                )
            ]
        return desc

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
            try:
                values = [float(v) for v in value]  # type: ignore[union-attr]
            except (TypeError, ValueError):
                raise InvalidParameterError(f"{where} must be a list of numbers") from None
            if self.length is not None and len(values) != self.length:
                raise InvalidParameterError(
                    f"{where} must have {self.length} values, got {len(values)}"
                )
            for v in values:
                self._check_number(v, where)
            return values
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise InvalidParameterError(f"{where} must be a number, got {value!r}")
        number = int(value) if isinstance(self.default, int) else float(value)
        self._check_number(float(number), where)
        return number

    def _check_number(self, v: float, where: str) -> None:
        if not math.isfinite(v):
            raise InvalidParameterError(f"{where} must be finite, got {v}")
        if self.min_value is not None and v < self.min_value:
            raise InvalidParameterError(f"{where} must be >= {self.min_value}, got {v}")
        if self.max_value is not None and v > self.max_value:
            raise InvalidParameterError(f"{where} must be <= {self.max_value}, got {v}")


def declare_parameters(node: Node, specs: Sequence[ParameterSpec]) -> dict[str, ParameterValue]:
    """Declare every parameter with its descriptor, read and validate it.

    Validation runs on the value given at start-up (parameter file or override)
    so that an invalid value stops the node before it does anything.
    Integers given for float parameters are accepted.
    """
    values: dict[str, ParameterValue] = {}
    for spec in specs:
        descriptor = spec.descriptor()
        # A YAML integer may set a float parameter; the type is checked by ``validate``.
        descriptor.dynamic_typing = True
        try:
            node.declare_parameter(spec.name, spec.default, descriptor)
        except ParameterException as exc:
            raise InvalidParameterError(f"parameter '{spec.name}': {exc}") from exc
        raw = node.get_parameter(spec.name).value
        if isinstance(spec.default, list):
            # rclpy cannot type an empty YAML list and leaves such a parameter unset.
            raw = [] if raw is None else list(raw)
        values[spec.name] = spec.validate(raw)
    return values


def warn_throttled(node: Node, key: str, message: str, period_s: float = 2.0) -> None:
    """Warn about rejected input at most once per ``period_s`` per ``key`` (wall clock).

    Every rejection is counted (see :func:`rejection_counts`), logged or not.
    """
    state: dict[str, list[float]] = node.__dict__.setdefault("_splitter_rejections", {})
    count, last = state.get(key, [0.0, -math.inf])
    count += 1
    now = time.monotonic()
    if now - last >= period_s:
        node.get_logger().warning(f"{message} (rejected {int(count)} so far)")
        last = now
    state[key] = [count, last]


def rejection_counts(node: Node) -> dict[str, int]:
    """How many inputs ``node`` rejected, per key passed to :func:`warn_throttled`."""
    state = node.__dict__.get("_splitter_rejections", {})
    return {key: int(count) for key, (count, _) in state.items()}
