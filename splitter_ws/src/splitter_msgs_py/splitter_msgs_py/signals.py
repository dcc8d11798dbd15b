"""Stop a node on SIGINT / SIGTERM between two callbacks, never in the middle of one.

rclpy's own signal handler (installed by ``rclpy.init`` unless told otherwise) answers
SIGINT and SIGTERM from a background thread: it shuts the contexts down while the
executor may be inside a callback, and for SIGINT it also chains to Python's handler,
which raises ``KeyboardInterrupt`` at whatever bytecode runs next. On a loaded machine
either race ends a node with exit code 1 instead of 0, with one of:

* ``RuntimeError: Unable to convert call argument '0' to Python object``: the
  ``KeyboardInterrupt`` fired inside a Python call made from rclpy's pybind11 code
  (``take_message`` converting a received message); reported upstream as
  ros/joint_state_publisher#117;
* ``RCLError: Failed to publish: publisher's context is invalid``: a callback published
  after the background thread had shut the context down;
* ``RCLError: failed to initialize wait set: the given context is not valid``.

This project's nodes therefore call ``rclpy.init(..., signal_handler_options=
SignalHandlerOptions.NO)``: :class:`StopRequest` records the signal in Python (the
handler runs in the main thread between bytecodes and only sets a flag), and
:func:`spin_until_stopped` checks the flag between callbacks. A second signal raises
``KeyboardInterrupt`` at once, for a node stuck inside a callback.
"""

from __future__ import annotations

import signal
import time
from collections.abc import Callable
from types import FrameType

from rclpy.duration import Duration
from rclpy.executors import Executor
from rclpy.node import Node
from rclpy.qos import ReliabilityPolicy

from splitter_msgs_py.executors import make_executor

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
SPIN_PERIOD_S = 0.1  # [s] longest wait for work before the stop flag is checked again
FLUSH_TIMEOUT_S = 2.0  # [s] longest wait for subscribers to acknowledge the last messages
DRAIN_QUIET_S = 0.2  # [s] a drain ends after this long without a new message
DRAIN_LIMIT_S = 5.0  # [s] and at the latest after this long
INTERNAL_TOPICS = ("/parameter_events", "/rosout")  # rclpy's own, not the graph's data


class StopRequest:
    """Set by the first SIGINT or SIGTERM after construction; the second one interrupts.

    Construct it in the main thread, before ``rclpy.init``.
    """

    def __init__(self) -> None:
        self._signal: int | None = None
        for signum in STOP_SIGNALS:
            signal.signal(signum, self._on_signal)

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        if self._signal is not None:
            raise KeyboardInterrupt
        self._signal = signum

    @property
    def requested(self) -> bool:
        """True once a stop signal arrived."""
        return self._signal is not None

    @property
    def signal_name(self) -> str | None:
        """Name of the signal that asked for the stop (``SIGINT``, ``SIGTERM``), if any."""
        return None if self._signal is None else signal.Signals(self._signal).name


def spin_until_stopped(
    node: Node,
    stop: StopRequest,
    *,
    executor: Executor | None = None,
    finished: Callable[[], bool] | None = None,
) -> None:
    """Execute the node's callbacks until a stop signal, ``finished()`` or a context shutdown.

    ``executor`` defaults to the project's (:func:`~splitter_msgs_py.executors.make_executor`)
    on the node's context; the node is added to it if it is not there yet.
    """
    if executor is None:
        executor = make_executor(node.context)
    if node not in executor.get_nodes():
        executor.add_node(node)
    while node.context.ok() and not stop.requested and not (finished is not None and finished()):
        executor.spin_once(timeout_sec=SPIN_PERIOD_S)
    if stop.requested:
        node.get_logger().info(f"{stop.signal_name}: stopping")
    flush_publishers(node)


def flush_publishers(node: Node, timeout_s: float = FLUSH_TIMEOUT_S) -> bool:
    """Wait until every matched reliable subscriber acknowledged the node's publications.

    A node that exits right after publishing (the simulator's last state at the end of a
    scenario) would otherwise take unacknowledged messages with it. Bounded by
    ``timeout_s`` in all; False (and a warning naming the topics) when it ran out.
    """
    if not node.context.ok():
        return False
    deadline = time.monotonic() + timeout_s
    unacked = []
    for publisher in node.publishers:
        if (
            publisher.qos_profile.reliability != ReliabilityPolicy.RELIABLE
            or publisher.topic_name in INTERNAL_TOPICS
        ):
            continue
        remaining = max(0.0, deadline - time.monotonic())
        if not publisher.wait_for_all_acked(Duration(seconds=remaining)):
            unacked.append(publisher.topic_name)
    if unacked:
        node.get_logger().warning(
            f"stopping with unacknowledged messages on {', '.join(unacked)} after {timeout_s:g} s"
        )
    return not unacked


def drain(
    executor: Executor,
    received: Callable[[], int],
    *,
    quiet_s: float = DRAIN_QUIET_S,
    limit_s: float = DRAIN_LIMIT_S,
) -> int:
    """Execute callbacks until ``received()`` stops growing for ``quiet_s`` (or ``limit_s``).

    A recorder stopped after the publishers has their last messages in its queues:
    this takes them before the bag is closed. Returns how many arrived while draining.
    """
    start = time.monotonic()
    first = last = received()
    quiet_since = start
    while time.monotonic() - start < limit_s and time.monotonic() - quiet_since < quiet_s:
        executor.spin_once(timeout_sec=min(SPIN_PERIOD_S, quiet_s))
        count = received()
        if count != last:
            last = count
            quiet_since = time.monotonic()
    return last - first
