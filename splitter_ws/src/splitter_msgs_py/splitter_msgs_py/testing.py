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
* :func:`assert_finite`: no NaN or infinity anywhere in a message.

For tests only (imports hypothesis).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import TypeVar

from hypothesis import strategies as st
from rclpy.node import Node
from rclpy.parameter import Parameter

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
