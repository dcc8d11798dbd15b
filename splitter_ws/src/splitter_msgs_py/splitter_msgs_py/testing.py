"""What the node tests share: any message content (hypothesis) and a node built for one example.

The property tests of every node's input callbacks (``test_*_node_inputs.py``) build
the node in-process, call its callbacks directly with messages whose contents
hypothesis draws, and check that nothing escapes and nothing non-finite is
published:

* :data:`SPECIAL_FLOATS`, :data:`ANY_FLOAT`, :data:`ANY_VECTOR3`, :data:`FLOAT_LIST`,
  :data:`ANY_TEXT`: numbers of any magnitude (NaN, infinities, 1e300, subnormals),
  and any string a DDS message can carry;
* :func:`node_under_test`: the node built with parameters in a test's context and
  destroyed after the example;
* :func:`assert_finite`: no NaN or infinity anywhere in a message;
* :func:`wrench_msg`, :func:`joint_state_msg`: messages of any content and stamp,
  built field by field (the conversions refuse what these tests send).

The in-process graph tests (``test_*_node.py``) spin the node under test with the
fake nodes around it: :func:`spun_together`, :func:`spin_until`, :func:`spin_for`.

For tests only (imports hypothesis).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from typing import TypeVar

from builtin_interfaces.msg import Time
from geometry_msgs.msg import WrenchStamped
from hypothesis import strategies as st
from rclpy.executors import Executor, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState

from splitter_msgs_py.inspection import non_finite_fields

SPECIAL_FLOATS = (
    math.nan,
    math.inf,
    -math.inf,
    1e300,
    -1e300,
    1e-300,
    -1e-300,
    0.0,
    -0.0,
    5e-324,
    1.7976931348623157e308,
    -1.7976931348623157e308,
)
ANY_FLOAT = st.one_of(st.floats(), st.sampled_from(SPECIAL_FLOATS))
ANY_VECTOR3 = st.tuples(ANY_FLOAT, ANY_FLOAT, ANY_FLOAT)
FLOAT_LIST = st.lists(ANY_FLOAT, max_size=27)  # up to two more than the 25 joints
# Any string a DDS message can carry (no lone surrogates: they are not UTF-8).
ANY_TEXT = st.text(st.characters(blacklist_categories=("Cs",)), max_size=12)

N = TypeVar("N", bound=Node)


@contextmanager
def node_under_test(
    make: Callable[..., N],
    context: object,
    overrides: Sequence[Parameter] = (),
    **parameters: object,
) -> Iterator[N]:
    """``make(context=, parameter_overrides=)`` (a node class) with ``overrides`` and
    ``parameters`` (name=value), destroyed on exit: a node for one hypothesis example.

    A test's fixture: ``return functools.partial(node_under_test, MyNode, ros_context)``.
    """
    values = [*overrides, *(Parameter(name, value=v) for name, v in parameters.items())]
    node = make(context=context, parameter_overrides=values)
    try:
        yield node
    finally:
        node.destroy_node()


def assert_finite(msg: object, path: str = "msg") -> None:
    """No NaN or infinity anywhere in a message (numeric diagnostics values included)."""
    assert non_finite_fields(msg, path) == []


def wrench_msg(stamp: Time, frame: str, force: Iterable, torque: Iterable) -> WrenchStamped:
    """A wrench of any content (each component as a float, unchecked)."""
    msg = WrenchStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = frame
    f, tau = msg.wrench.force, msg.wrench.torque
    f.x, f.y, f.z = (float(v) for v in force)
    tau.x, tau.y, tau.z = (float(v) for v in torque)
    return msg


def joint_state_msg(
    stamp: Time,
    joint_names: Iterable[str],
    position: Iterable,
    velocity: Iterable = (),
    effort: Iterable = (),
) -> JointState:
    """A joint state of any content and length (floats, unchecked; no velocity, effort)."""
    msg = JointState()
    msg.header.stamp = stamp
    msg.name = list(joint_names)
    msg.position = [float(v) for v in position]
    msg.velocity = [float(v) for v in velocity]
    msg.effort = [float(v) for v in effort]
    return msg


@contextmanager
def spun_together(context: object, *nodes: Node) -> Iterator[SingleThreadedExecutor]:
    """One executor in ``context`` for ``nodes``; on exit it shuts down and they are destroyed."""
    executor = SingleThreadedExecutor(context=context)
    for node in nodes:
        executor.add_node(node)
    try:
        yield executor
    finally:
        executor.shutdown()
        for node in nodes:
            node.destroy_node()


@contextmanager
def publishers_on(
    context: object, node: Node, topics: dict[str, type], count: int = 2, timeout_s: float = 5.0
) -> Iterator[Node]:
    """``count`` publishers on each of ``topics`` (name: message type), from one other node,
    seen by ``node``'s graph (a test failure after ``timeout_s`` [s]); destroyed on exit."""
    import rclpy

    others = rclpy.create_node("publishers_on", context=context)
    try:
        for topic, msg_type in topics.items():
            for _ in range(count):
                others.create_publisher(msg_type, topic, 10)
        deadline = time.monotonic() + timeout_s
        while any(node.count_publishers(t) < count for t in topics):
            assert time.monotonic() < deadline, f"{node.get_name()} sees no {count} publishers"
            time.sleep(0.01)
        yield others
    finally:
        others.destroy_node()


def spin_until(
    executor: Executor, done: Callable[[], bool], timeout_s: float = 10.0, what: str = ""
) -> None:
    """Spin ``executor`` until ``done()``; a test failure after ``timeout_s`` [s] of wall time."""
    deadline = time.monotonic() + timeout_s
    while not done():
        assert time.monotonic() < deadline, f"timed out ({timeout_s} s) waiting for {what or done}"
        executor.spin_once(timeout_sec=0.01)


def spin_for(executor: Executor, seconds: float) -> None:
    """Spin ``executor`` for ``seconds`` of wall time."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.01)
