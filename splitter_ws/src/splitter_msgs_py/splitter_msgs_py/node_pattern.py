"""The house's node pattern: one ``main`` and one input-stamp rule for every node.

* :func:`run_node` is the Jazzy ``main()`` idiom once: ``rclpy.init`` without
  rclpy's signal handler (:mod:`splitter_msgs_py.signals`), the node built,
  spun until a stop signal, its own end or a shutdown; an invalid parameter
  stops it with exit code 1 and a message naming the parameter;
  ``KeyboardInterrupt`` and ``ExternalShutdownException`` end it quietly;
  ``destroy_node`` and ``try_shutdown`` always run.
* :func:`sim_clock_ns` is a node's simulated time (None before ``/clock``);
  :func:`default_sim_time` starts a node on it unless told otherwise.
* :func:`admitted_stamp` applies the stamp rules of
  :class:`~splitter_msgs_py.core.stamps.StampGate` to a message and turns a
  rejection into a throttled warning (counted for ``/diagnostics``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.logging import get_logger
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions

from splitter_msgs_py.conversions import checked_stamp_from_msg
from splitter_msgs_py.core.stamps import MessageValidationError, StampGate
from splitter_msgs_py.parameters import USE_SIM_TIME, InvalidParameterError, warn_throttled
from splitter_msgs_py.signals import StopRequest, spin_until_stopped

N = TypeVar("N", bound=Node)


def run_node(
    make_node: Callable[[StopRequest], N],
    name: str,
    args: list[str] | None = None,
    *,
    spin: Callable[[N, StopRequest], None] | None = None,
    exit_code: Callable[[N], int] | None = None,
    before_destroy: Callable[[N], None] | None = None,
) -> int:
    """Run one node the house's way; the body of every node's ``main``.

    ``make_node(stop)`` builds the node (it may keep ``stop`` to end itself).
    ``spin(node, stop)`` replaces the default spin, which runs until a stop signal,
    or a context shutdown (:func:`~splitter_msgs_py.signals.spin_until_stopped`).
    ``exit_code(node)`` gives the code of a run that started (default 0);
    ``before_destroy(node)`` runs before the node is destroyed (a last report).
    """
    stop = StopRequest()
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    node: N | None = None
    try:
        node = make_node(stop)
        if spin is None:
            spin_until_stopped(node, stop)
        else:
            spin(node, stop)
    except InvalidParameterError as exc:
        get_logger(name).fatal(f"invalid parameter, not starting: {exc}")
        return 1
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            if before_destroy is not None:
                before_destroy(node)
            node.destroy_node()
        rclpy.try_shutdown()
    return 0 if node is None or exit_code is None else exit_code(node)


def default_sim_time(node_kwargs: dict[str, Any]) -> dict[str, Any]:
    """A node's keyword arguments with ``use_sim_time`` True unless an override names it."""
    overrides = list(node_kwargs.get("parameter_overrides") or [])
    if not any(p.name == USE_SIM_TIME for p in overrides):
        overrides.append(Parameter(USE_SIM_TIME, value=True))
    return {**node_kwargs, "parameter_overrides": overrides}


def sim_clock_ns(node: Node) -> int | None:
    """The node's simulated time [ns]; None on wall-clock time or before the first /clock."""
    clock = node.get_clock()
    if not getattr(clock, "ros_time_is_active", False):
        return None  # wall-clock time says nothing about simulated stamps
    now = clock.now().nanoseconds
    return now if now > 0 else None


def admitted_stamp(
    node: Node,
    gate: StampGate,
    topic: str,
    msg: object,
    *,
    key: str | None = None,
    clock_ns: int | Callable[[], int | None] | None = None,
    not_before_ns: int | None = None,
    consequence: str = "dropped, the node keeps its last good data",
) -> int | None:
    """The stamp [ns] of ``msg`` if the node may use it, else None (warned, counted).

    Rejected: a malformed or negative stamp, and whatever :meth:`StampGate.admit`
    refuses. ``clock_ns`` defaults to the node's simulated time; ``key`` names
    the rejection count (default: ``topic``).
    """
    try:
        t_ns = checked_stamp_from_msg(msg.header.stamp)  # type: ignore[attr-defined]
        clock = (lambda: sim_clock_ns(node)) if clock_ns is None else clock_ns
        return gate.admit(topic, t_ns, clock, not_before_ns)
    except MessageValidationError as exc:
        warn_throttled(node, key or topic, f"rejected {topic}: {exc}; {consequence}")
        return None
