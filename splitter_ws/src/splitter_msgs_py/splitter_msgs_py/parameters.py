"""Declared, described and validated node parameters, and throttled input warnings.

A node lists its parameters as :class:`ParameterSpec` objects and calls
:func:`declare_parameters` in ``__init__``: each is declared with a
``ParameterDescriptor`` (description, range) and its value validated; an
invalid value raises :class:`InvalidParameterError` naming the parameter, which
stops the node at start-up with that message.

At runtime (``ros2 param set``, rqt_reconfigure, the ``~/set_parameters``
service) every parameter is one of two kinds (docs/ARCHITECTURE.md, "Parameters"):

* read-only (the default): read at start-up only. Its descriptor says
  ``read_only``, so rclpy refuses a set with "Trying to set a read-only
  parameter: <name>." before anything else sees it.
* live (``ParameterSpec(live=True)``): one set-parameters callback per node
  validates every incoming value with its spec (type, finiteness, range,
  choices, length) and refuses an invalid one with a reason naming the
  parameter; a valid change is handed to the node's ``on_live_change`` function,
  which applies it to the node's core object (or refuses it, e.g. when it needs
  a rebuild), then logged and counted (:func:`parameter_diagnostics`, on the
  node's ``/diagnostics``).

Any other runtime set is refused: rclpy's own ``use_sim_time`` (the graph's
clock is chosen by its launcher, and rclpy would switch it live) and any
parameter a node declared by hand without marking it read-only. Nothing is
accepted and ignored.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.parameter import Parameter

from splitter_msgs_py.core.parameter_fields import (
    InvalidParameterError,
    ParameterSpec,
    ParameterValue,
    parameter_fields,
)

# Applies a live change: the node's validated values after the change (every
# parameter declared through declare_parameters). Raises InvalidParameterError or
# ValueError to refuse it (nothing applied).
LiveApply = Callable[[Mapping[str, ParameterValue]], None]

READ_ONLY_NOTE = " [read-only: read at start-up]"
LIVE_NOTE = " [live: a valid runtime change is applied]"
USE_SIM_TIME = "use_sim_time"


def descriptor(spec: ParameterSpec) -> ParameterDescriptor:
    """The ROS descriptor of ``spec``: description, range and read-only."""
    text = spec.description
    if spec.choices:
        text += f" (one of: {', '.join(spec.choices)})"
    if spec.length is not None:
        text += f" ({spec.length} values)"
    text += LIVE_NOTE if spec.live else READ_ONLY_NOTE
    desc = ParameterDescriptor(name=spec.name, description=text, read_only=not spec.live)
    lo, hi = spec.min_value, spec.max_value
    if isinstance(spec.default, bool) or (lo is None and hi is None):
        return desc
    if isinstance(spec.default, int) and spec.length is None:
        desc.integer_range = [
            IntegerRange(
                from_value=int(lo if lo is not None else -(2**31)),
                to_value=int(hi if hi is not None else 2**31 - 1),
                step=0,
            )
        ]
    elif isinstance(spec.default, float) and spec.length is None:
        desc.floating_point_range = [
            FloatingPointRange(
                from_value=float(lo if lo is not None else -math.inf),
                to_value=float(hi if hi is not None else math.inf),
                step=0.0,
            )
        ]
    return desc


@dataclass
class _NodeParameters:
    """A node's declared specs, their current values and the live-change handlers."""

    specs: dict[str, ParameterSpec] = field(default_factory=dict)
    values: dict[str, ParameterValue] = field(default_factory=dict)
    handlers: list[tuple[frozenset[str], LiveApply]] = field(default_factory=list)
    changes: int = 0
    last_change: str = ""


def _state(node: Node) -> _NodeParameters | None:
    return node.__dict__.get("_splitter_parameters")


def declare_parameters(
    node: Node,
    specs: Sequence[ParameterSpec],
    on_live_change: LiveApply | None = None,
) -> dict[str, ParameterValue]:
    """Declare every parameter with its descriptor, read and validate it.

    Validation runs on the value given at start-up (parameter file or override)
    so that an invalid value stops the node before it does anything.
    Integers given for float parameters are accepted.

    ``on_live_change`` is required when a spec is live: it applies a validated
    runtime change (module docstring). The first call on a node installs its
    set-parameters callbacks; later calls add their specs to them.
    """
    live = [spec.name for spec in specs if spec.live]
    if live and on_live_change is None:
        raise TypeError(f"live parameters {live} need an on_live_change function")
    values: dict[str, ParameterValue] = {}
    for spec in specs:
        desc = descriptor(spec)
        # A YAML integer may set a float parameter; the type is checked by ``validate``.
        desc.dynamic_typing = True
        try:
            node.declare_parameter(spec.name, spec.default, desc)
        except ParameterException as exc:
            raise InvalidParameterError(f"parameter '{spec.name}': {exc}") from exc
        raw = node.get_parameter(spec.name).value
        if isinstance(spec.default, list):
            # rclpy cannot type an empty YAML list and leaves such a parameter unset.
            raw = [] if raw is None else list(raw)
        values[spec.name] = spec.validate(raw)
    state = _state(node)
    if state is None:
        state = _NodeParameters()
        node.__dict__["_splitter_parameters"] = state
        node.add_pre_set_parameters_callback(lambda params: _as_floats(state, params))
        node.add_on_set_parameters_callback(lambda params: _on_set(node, state, params))
    state.specs.update({spec.name: spec for spec in specs})
    state.values.update(values)
    if live:
        state.handlers.append((frozenset(live), on_live_change))  # type: ignore[arg-type]
    return values


def _as_floats(state: _NodeParameters, params: list[Parameter]) -> list[Parameter]:
    """An integer (array) given for a float (array) parameter, as the float it stands for."""
    converted = []
    for p in params:
        spec = state.specs.get(p.name)
        if spec is not None and spec.is_float and p.type_ == Parameter.Type.INTEGER:
            converted.append(Parameter(p.name, Parameter.Type.DOUBLE, float(p.value)))
        elif spec is not None and spec.is_float and p.type_ == Parameter.Type.INTEGER_ARRAY:
            values = [float(v) for v in p.value]
            converted.append(Parameter(p.name, Parameter.Type.DOUBLE_ARRAY, values))
        else:
            converted.append(p)
    return converted


def _refused(reason: str) -> SetParametersResult:
    return SetParametersResult(successful=False, reason=reason)


def _on_set(node: Node, state: _NodeParameters, params: list[Parameter]) -> SetParametersResult:
    """Validate a runtime set, apply it live or refuse it with a reason."""
    result = _check_and_apply(node, state, params)
    if not result.successful:
        # rclpy typed the (dynamically typed) descriptor after the refused value before
        # asking: give it back the type of the value kept (``ros2 param describe``)
        for p in params:
            if node.has_parameter(p.name):
                node.describe_parameter(p.name).type = node.get_parameter(p.name).type_.value
    return result


def _check_and_apply(
    node: Node, state: _NodeParameters, params: list[Parameter]
) -> SetParametersResult:
    changes: dict[str, ParameterValue] = {}
    for p in params:
        if p.name == USE_SIM_TIME:
            return _refused(
                f"parameter '{USE_SIM_TIME}' is read at start-up: the graph's clock (simulated "
                "/clock or wall time) is chosen by its launcher; restart the node to change it"
            )
        if not node.has_parameter(p.name):
            continue  # a declaration: checked where it is declared
        spec = state.specs.get(p.name)
        if spec is None or not spec.live:
            return _refused(
                f"parameter '{p.name}' is read at start-up only; restart the node to change it"
            )
        try:
            changes[p.name] = spec.validate(p.value)
        except InvalidParameterError as exc:
            return _refused(str(exc))
    if not changes:
        return SetParametersResult(successful=True)
    values = {**state.values, **changes}
    for handled, apply in state.handlers:
        if handled & changes.keys():
            try:
                apply(values)
            except ValueError as exc:  # InvalidParameterError included
                names = ", ".join(f"'{name}'" for name in changes)
                return _refused(f"parameter {names} not applied: {exc}")
    state.values = values
    for name, value in changes.items():
        state.changes += 1
        state.last_change = f"{name} = {value}"
        node.get_logger().info(f"parameter '{name}' set to {value}: applied live")
    return SetParametersResult(successful=True)


def live_parameter_values(node: Node) -> dict[str, ParameterValue]:
    """The validated values of ``node``'s parameters, live changes included."""
    state = _state(node)
    return {} if state is None else dict(state.values)


def parameter_diagnostics(node: Node) -> dict[str, int | str]:
    """Live parameter changes applied so far and the last one, for ``/diagnostics``."""
    state = _state(node)
    if state is None:
        return {"parameter_changes": 0}
    values: dict[str, int | str] = {"parameter_changes": state.changes}
    if state.last_change:
        values["last_parameter_change"] = state.last_change
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


def specs_from_config(
    config_class: type, *, exclude: Sequence[str] = (), live: Sequence[str] = ()
) -> tuple[ParameterSpec, ...]:
    """The parameter specs of the fields of ``config_class`` marked with ``parameter_field``.

    ``exclude``: fields the node does not expose; ``live``: fields made live here
    although the core marks them read-only (a node that can apply them).
    """
    return tuple(
        replace(spec, live=spec.live or name in live)
        for name, _default, spec in parameter_fields(config_class)
        if name not in exclude
    )


def config_from_values(config_class: type, values: Mapping[str, ParameterValue], **others):
    """``config_class`` built from the node's validated ``values`` of its parameter fields.

    ``others`` sets fields that are not parameters (or overrides). A value the
    config refuses (its ``__post_init__`` raises ``ValueError``) becomes an
    :class:`InvalidParameterError`, which stops the node naming the field.
    """
    kwargs: dict[str, object] = {}
    for name, default, _info in parameter_fields(config_class):
        if name in values:
            value = values[name]
            kwargs[name] = tuple(value) if isinstance(default, tuple) else value  # type: ignore[arg-type]
    kwargs.update(others)
    try:
        return config_class(**kwargs)
    except ValueError as exc:
        raise InvalidParameterError(f"{config_class.__name__}: {exc}") from exc
