"""gait_phase_manager: every subscription callback survives any message (property tests).

The node is built in-process and its callbacks (odom, both contact wrenches, joint
states, inertia) are called directly, interleaved with complete good ticks, with
messages whose contents hypothesis draws: floats of any magnitude, arrays of any
length, any joint names and frame ids, stamps of any value (0, backwards, far
ahead, out-of-range fields). Nothing may escape a callback; a message rejected for
its stamp is filed under no tick and leaves the last good message of its topic; one
rejected for its contents leaves it too; everything the node publishes is finite.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Vector3Stamped
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from nav_msgs.msg import Odometry
from rclpy.parameter import Parameter

from splitter_model.actuators import TETHER_INDEX
from splitter_mpc.core.gait import GaitPhase
from splitter_mpc.core.gait_tick import (
    MAX_BODY_RATE_RAD_S,
    MAX_CONTACT_FORCE_N,
    MAX_POSITION_M,
    MAX_SPEED_M_S,
    MAX_TETHER_LENGTH_M,
)
from splitter_mpc.core.tick_inputs import MAX_PENDING_TICKS
from splitter_mpc.gait_phase_manager_node import GaitPhaseManagerNode
from splitter_msgs_py import conversions as conv
from splitter_msgs_py import names
from splitter_msgs_py.core.stamps import MAX_STAMP_LEAD_NS
from splitter_msgs_py.inspection import record_publications
from splitter_msgs_py.parameters import rejection_counts
from splitter_msgs_py.testing import (
    ANY_FLOAT,
    ANY_TEXT,
    ANY_VECTOR3,
    FLOAT_LIST,
    assert_finite,
    joint_state_msg,
    node_under_test,
    wrench_msg,
)

# An overflow inside a callback means an implausible number got past validation.
pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")

MS = 1_000_000  # [ns]
TICK_NS = 10 * MS
NS_PER_S = 1_000_000_000
PITCH_RAD = math.radians(10.0)
Q_BODY_WXYZ = (math.cos(PITCH_RAD / 2), 0.0, math.sin(PITCH_RAD / 2), 0.0)
INERTIA_KG_M2 = (0.48, 141.36, 141.36)
PLAN = [
    Parameter("jump_times_s", value=[0.02]),
    Parameter("jump_forces_n", value=[40.0, 0.0, 40.0]),
    Parameter("jump_durations_s", value=[0.03]),
    Parameter("jump_hemis", value=["auto"]),
    Parameter("landed_dwell_s", value=0.02),
    Parameter("w_ref_rad_s", value=[0.0, 1.0, 0.0]),
    Parameter("attitude_reference", value="momentum_aligned"),  # subscribes to the inertia
]
SMALL_VECTOR3 = st.tuples(*[st.floats(-2.0, 2.0)] * 3)
FRAME = st.one_of(st.sampled_from([names.WORLD_FRAME, names.BASE_FRAME, ""]), ANY_TEXT)
# k ticks after the example's clock / an off-grid time / zero / far ahead / raw fields
STAMP = st.one_of(
    st.tuples(st.just("tick"), st.integers(0, 3)),
    st.tuples(st.just("tick"), st.integers(-2, 3)),
    st.tuples(st.just("off"), st.integers(1, TICK_NS - 1)),
    st.just(("zero",)),
    st.tuples(st.just("ahead"), st.sampled_from([NS_PER_S + 1, 100 * NS_PER_S])),
    st.tuples(st.just("raw"), st.integers(-(2**31), 2**31 - 2), st.integers(0, 2**32 - 1)),
)
QUATERNION = st.one_of(st.just(Q_BODY_WXYZ), st.tuples(ANY_FLOAT, ANY_FLOAT, ANY_FLOAT, ANY_FLOAT))
ODOM = st.tuples(
    st.one_of(st.just((names.WORLD_FRAME, names.BASE_FRAME)), st.tuples(FRAME, FRAME)),
    st.one_of(st.tuples(*[st.floats(-5.0, 5.0)] * 3), ANY_VECTOR3),
    QUATERNION,
    st.one_of(SMALL_VECTOR3, ANY_VECTOR3),
    st.one_of(SMALL_VECTOR3, ANY_VECTOR3),
)
GOOD_ODOM = st.tuples(
    st.just((names.WORLD_FRAME, names.BASE_FRAME)),
    st.tuples(*[st.floats(-5.0, 5.0)] * 3),
    st.just(Q_BODY_WXYZ),
    SMALL_VECTOR3,
    SMALL_VECTOR3,
)
GOOD_CONTACT = st.tuples(
    st.sampled_from(names.CONTACT_WRENCHES),
    st.just(names.WORLD_FRAME),
    st.tuples(st.just(0.0), st.just(0.0), st.floats(0.0, 50.0)),
    SMALL_VECTOR3,
)
CONTACT = st.tuples(
    st.sampled_from(names.CONTACT_WRENCHES),
    st.one_of(st.just(names.WORLD_FRAME), FRAME),
    st.one_of(st.tuples(st.just(0.0), st.just(0.0), st.floats(0.0, 50.0)), ANY_VECTOR3),
    ANY_VECTOR3,
)
JOINTS = st.one_of(
    st.tuples(st.permutations(names.JOINT_NAMES).map(list), st.floats(0.0, 8.0)).map(
        lambda x: (x[0], [x[1] if n == names.TETHER_JOINT else 0.0 for n in x[0]])
    ),
    st.tuples(
        st.one_of(
            st.permutations(names.JOINT_NAMES).map(list),
            st.lists(st.one_of(st.sampled_from(names.JOINT_NAMES), ANY_TEXT), max_size=27),
        ),
        FLOAT_LIST,
    ),
)
INERTIA = st.tuples(
    st.one_of(st.just(names.BASE_FRAME), FRAME),
    st.one_of(st.tuples(*[st.floats(0.1, 200.0)] * 3), ANY_VECTOR3),
)
STEP = st.one_of(
    st.tuples(st.just("good tick"), st.integers(0, 2), st.none()),
    st.tuples(st.just(names.ODOM), STAMP, st.one_of(GOOD_ODOM, ODOM)),
    st.tuples(st.just("contact"), STAMP, st.one_of(GOOD_CONTACT, CONTACT)),
    st.tuples(st.just(names.JOINT_STATES), STAMP, JOINTS),
    st.tuples(st.just(names.INERTIA), STAMP, INERTIA),
)
SETTINGS = settings(
    max_examples=100,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)


# --- messages -------------------------------------------------------------------------------
def odom_msg(stamp: Time, content: tuple) -> Odometry:
    """``content``: (frame ids, position, orientation (w, x, y, z), velocity, body rate)."""
    frames, position, q_wxyz, velocity, rate = content
    msg = Odometry()
    msg.header.stamp = stamp
    msg.header.frame_id, msg.child_frame_id = frames
    p, o = msg.pose.pose.position, msg.pose.pose.orientation
    p.x, p.y, p.z = (float(v) for v in position)
    o.w, o.x, o.y, o.z = (float(v) for v in q_wxyz)
    v, w = msg.twist.twist.linear, msg.twist.twist.angular
    v.x, v.y, v.z = (float(c) for c in velocity)
    w.x, w.y, w.z = (float(c) for c in rate)
    return msg


def vector3_msg(stamp: Time, frame: str, vector) -> Vector3Stamped:
    msg = Vector3Stamped()
    msg.header.stamp = stamp
    msg.header.frame_id = frame
    msg.vector.x, msg.vector.y, msg.vector.z = (float(v) for v in vector)
    return msg


def send_good_tick(node: GaitPhaseManagerNode, t_ns: int) -> None:
    """A complete, valid set of the tick's inputs, as the simulator publishes it."""
    node._on_input(
        names.ODOM,
        conv.odom_to_msg(t_ns, (0.0, 0.0, 0.45), Q_BODY_WXYZ, (0.0, 0.0, 0.0), (0.5, -0.5, 0.5)),
    )
    send_good_tick_without_odom(node, t_ns)


class Stamps:
    """The example's clock and an independent model of which stamps the node must accept."""

    def __init__(self) -> None:
        self.t_ns = 0  # the next good tick
        self.last: dict[str, int] = {}

    def make(self, spec: tuple) -> Time:
        kind = spec[0]
        if kind == "raw":
            return Time(sec=spec[1], nanosec=spec[2])
        t = {
            "tick": lambda: self.t_ns + spec[1] * TICK_NS,
            "off": lambda: self.t_ns + spec[1],
            "zero": lambda: 0,
            "ahead": lambda: max(self.last.values(), default=self.t_ns) + spec[1],
        }[kind]()
        t = max(t, 0)
        return Time(sec=t // NS_PER_S, nanosec=t % NS_PER_S)

    def acceptable(self, topic: str, stamp: Time) -> bool:
        if stamp.sec < 0 or stamp.nanosec >= NS_PER_S:
            return False
        t = stamp.sec * NS_PER_S + stamp.nanosec
        if topic in self.last and t < self.last[topic]:
            return False
        latest = max(self.last.values(), default=None)
        return latest is None or t <= latest + MAX_STAMP_LEAD_NS

    def accepted(self, topic: str, t_ns: int) -> None:
        self.last[topic] = max(t_ns, self.last.get(topic, t_ns))


@pytest.fixture
def make_node(ros_context):
    """Builds a node that lives for one hypothesis example (``with make_node() as node``)."""
    return functools.partial(node_under_test, GaitPhaseManagerNode, ros_context, PLAN)


def rejections(node: GaitPhaseManagerNode) -> int:
    """Rejected inputs (a tick answered before any good input is warned about too)."""
    return sum(n for key, n in rejection_counts(node).items() if key != "no_good_input")


def _pending(node: GaitPhaseManagerNode) -> dict:
    return {t: dict(inputs) for t, inputs in node.tick.ticks.pending.items()}


def _same_pending(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(
        a[t].keys() == b[t].keys() and all(a[t][k] is b[t][k] for k in a[t]) for t in a
    )


def _assert_last_good_plausible(node: GaitPhaseManagerNode) -> None:
    good = node.tick.ticks.last_good
    if names.ODOM in good:
        odom = good[names.ODOM]
        assert np.all(np.abs(odom.position_m) <= MAX_POSITION_M)
        assert np.all(np.abs(odom.velocity_m_s) <= MAX_SPEED_M_S)
        assert np.all(np.abs(odom.angular_velocity_rad_s) <= MAX_BODY_RATE_RAD_S)
    for topic in names.CONTACT_WRENCHES:
        if topic in good:
            assert np.all(np.abs(good[topic]) <= MAX_CONTACT_FORCE_N)
    if names.JOINT_STATES in good:
        assert 0.0 < good[names.JOINT_STATES] <= MAX_TETHER_LENGTH_M
    if names.INERTIA in good:
        assert np.all(good[names.INERTIA] > 0.0)


def _assert_published_sane(published: dict[str, list]) -> None:
    stamps = [conv.stamp_from_msg(m.header.stamp) for m in published[names.JUMP_COMMAND]]
    assert stamps == sorted(set(stamps)), "one jump command per tick, ticks increasing"
    assert all(t % TICK_NS == 0 for t in stamps)
    phases = {p.value for p in GaitPhase}
    assert all(m.data in phases for m in published[names.GAIT_PHASE])
    for topic, messages in published.items():
        for msg in messages:
            assert_finite(msg, topic)


@SETTINGS
@given(steps=st.lists(STEP, max_size=14))
def test_input_callbacks_survive_any_message(make_node, steps) -> None:
    with make_node() as node:
        published = record_publications(node)
        stamps = Stamps()
        for kind, spec, content in steps:
            if kind == "good tick":
                stamps.t_ns += spec * TICK_NS
                send_good_tick(node, stamps.t_ns)
                for topic in node.tick.ticks.inputs:
                    stamps.accepted(topic, stamps.t_ns)
                stamps.t_ns += TICK_NS
                continue
            stamp = stamps.make(spec)
            topic = content[0] if kind == "contact" else kind
            acceptable = stamps.acceptable(topic, stamp)
            last_good, pending = node.tick.ticks.last_good.get(topic), _pending(node)
            rejected_before = rejections(node)
            if kind == names.ODOM:
                node._on_input(names.ODOM, odom_msg(stamp, content))
            elif kind == "contact":
                node._on_input(topic, wrench_msg(stamp, *content[1:]))
            elif kind == names.JOINT_STATES:
                node._on_input(names.JOINT_STATES, joint_state_msg(stamp, *content))
            else:
                node._on_input(names.INERTIA, vector3_msg(stamp, *content))
            rejected = rejections(node) > rejected_before
            event(f"{kind}: {'rejected' if rejected else 'accepted'}")
            if not acceptable:  # filed under no tick, the last good message kept
                assert rejected
                assert node.tick.ticks.last_good.get(topic) is last_good
                assert _same_pending(_pending(node), pending)
                continue
            stamps.accepted(topic, conv.stamp_from_msg(stamp))
            if rejected:
                assert node.tick.ticks.last_good.get(topic) is last_good
            else:
                assert node.tick.ticks.last_good[topic] is not last_good
            assert len(node.tick.ticks.pending) <= MAX_PENDING_TICKS
            _assert_last_good_plausible(node)
        # good ticks still complete and are answered afterwards
        answered = len(published[names.JUMP_COMMAND])
        t_next = max([stamps.t_ns, *stamps.last.values()]) // TICK_NS * TICK_NS + TICK_NS
        send_good_tick(node, t_next)
        assert len(published[names.JUMP_COMMAND]) == answered + 1
        _assert_published_sane(published)


# --- stamps that used to be taken as they came ---------------------------------------------
def test_stamp_zero_after_ticks_is_rejected_and_keeps_the_last_good(make_node) -> None:
    with make_node() as node:
        published = record_publications(node)
        for k in range(5):
            send_good_tick(node, k * TICK_NS)
        good = dict(node.tick.ticks.last_good)
        node._on_input(
            names.ODOM, conv.odom_to_msg(0, (9.0, 9.0, 9.0), Q_BODY_WXYZ, (5, 0, 0), (3, 0, 0))
        )
        assert all(node.tick.ticks.last_good[topic] is sample for topic, sample in good.items())
        assert rejection_counts(node) == {names.ODOM: 1}
        send_good_tick(node, 5 * TICK_NS)
        assert len(published[names.JUMP_COMMAND]) == 6
        _assert_published_sane(published)


def test_a_far_ahead_tick_does_not_lock_the_node_out(make_node) -> None:
    """A complete set of inputs stamped 1000 s ahead would have been answered, and every
    later (correct) tick ignored as 'late'; now it is rejected and ticks go on."""
    with make_node() as node:
        published = record_publications(node)
        send_good_tick(node, 0)
        send_good_tick(node, 1000 * NS_PER_S)
        assert node.tick.ticks.pending == {}
        for k in range(1, 4):
            send_good_tick(node, k * TICK_NS)
        stamps = [conv.stamp_from_msg(m.header.stamp) for m in published[names.JUMP_COMMAND]]
        assert stamps == [0, TICK_NS, 2 * TICK_NS, 3 * TICK_NS]
        assert rejection_counts(node) == dict.fromkeys(node.tick.ticks.inputs, 1)


@pytest.mark.parametrize(
    ("label", "mutate"),
    [
        ("position 1e300", lambda m: setattr(m.pose.pose.position, "z", 1e300)),
        ("velocity 1e300", lambda m: setattr(m.twist.twist.linear, "x", -1e300)),
        ("rate 1e300", lambda m: setattr(m.twist.twist.angular, "y", 1e300)),
        ("max float velocity", lambda m: setattr(m.twist.twist.linear, "x", 1.7e308)),
        ("unknown child frame", lambda m: setattr(m, "child_frame_id", "hemi_c")),
    ],
)
def test_implausible_odom_is_rejected_and_its_tick_answered(make_node, label, mutate) -> None:
    with make_node() as node:
        published = record_publications(node)
        send_good_tick(node, 0)
        good = node.tick.ticks.last_good[names.ODOM]
        bad = conv.odom_to_msg(TICK_NS, (0, 0, 0.45), Q_BODY_WXYZ, (0, 0, 0), (0.5, -0.5, 0.5))
        mutate(bad)
        node._on_input(names.ODOM, bad)
        assert node.tick.ticks.last_good[names.ODOM] is good, label
        send_good_tick_without_odom(node, TICK_NS)
        assert len(published[names.JUMP_COMMAND]) == 2  # answered from the last good odom
        assert rejection_counts(node) == {names.ODOM: 1}
        _assert_published_sane(published)


def send_good_tick_without_odom(node: GaitPhaseManagerNode, t_ns: int) -> None:
    stamp = conv.stamp_to_msg(t_ns)
    for topic in names.CONTACT_WRENCHES:
        node._on_input(topic, wrench_msg(stamp, names.WORLD_FRAME, (0, 0, 20.0), (0, 0, 0)))
    joints = np.zeros(names.N_JOINTS)
    joints[TETHER_INDEX] = 2.8
    node._on_input(names.JOINT_STATES, conv.joint_state_to_msg(t_ns, joints))
    node._on_input(names.INERTIA, conv.vector3_to_msg(t_ns, INERTIA_KG_M2, names.BASE_FRAME))
