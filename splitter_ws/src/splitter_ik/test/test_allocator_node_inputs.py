"""ik_tether_allocator: every subscription callback survives any message (property tests).

The node is built in-process and its callbacks are called directly with messages
whose contents hypothesis draws: floats of any magnitude (NaN, infinities, 1e300,
1e-300), stamps of any value (0, backwards, far ahead, out-of-range fields) and any
frame id. Nothing may escape a callback, a rejected message leaves the node's state
as it was (counted as a rejection), and everything the node publishes is finite.
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
from sensor_msgs.msg import Imu

from splitter_ik.core.allocator_tick import MAX_BODY_RATE_RAD_S
from splitter_ik.core.projection import project_inertia, reachable_inertia_bounds
from splitter_ik.ik_tether_allocator_node import IkTetherAllocatorNode
from splitter_model.model import RobotModel, principal_inertia
from splitter_msgs_py import conversions as conv
from splitter_msgs_py import names
from splitter_msgs_py.core.stamps import MAX_STAMP_LEAD_NS
from splitter_msgs_py.inspection import record_publications
from splitter_msgs_py.parameters import rejection_counts
from splitter_msgs_py.testing import (
    ANY_FLOAT,
    ANY_TEXT,
    ANY_VECTOR3,
    assert_finite,
    node_under_test,
)

# An overflow inside a callback means an implausible number got past validation.
pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")

MODEL = RobotModel()
TICK_NS = 10_000_000  # [ns] the allocator's control period
NS_PER_S = 1_000_000_000
TARGET = principal_inertia(MODEL, [2.0, 0.3, 0.15])  # [kg m^2] a reachable setpoint

FRAME = st.one_of(st.just(names.BASE_FRAME), st.sampled_from([names.WORLD_FRAME, ""]), ANY_TEXT)
PLAUSIBLE_INERTIA = st.tuples(*[st.floats(0.1, 200.0)] * 3)  # [kg m^2]
# A stamp: k ticks after the newest "next" stamp of the example, zero, or raw fields.
STAMP = st.one_of(
    st.tuples(st.just("next"), st.integers(0, 3)),
    st.tuples(st.just("next"), st.integers(0, 1)),
    st.just(("zero",)),
    st.tuples(st.just("raw"), st.integers(-(2**31), 2**31 - 1), st.integers(0, 2**32 - 1)),
)
SETTINGS = settings(
    max_examples=100,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)


class Clock:
    """The example's notion of 'now' for the "next" stamps."""

    def __init__(self) -> None:
        self.t_ns = 0

    def stamp(self, spec: tuple) -> Time:
        if spec[0] == "next":
            self.t_ns += spec[1] * TICK_NS
            return Time(sec=self.t_ns // NS_PER_S, nanosec=self.t_ns % NS_PER_S)
        if spec[0] == "zero":
            return Time()
        return Time(sec=spec[1], nanosec=spec[2])


def total_rejections(node) -> int:
    """Rejected inputs (a projected setpoint is warned about too, but it is no rejection)."""
    return sum(n for key, n in rejection_counts(node).items() if key != "projected")


def vector3_msg(stamp: Time, vector, frame: str = names.BASE_FRAME) -> Vector3Stamped:
    msg = Vector3Stamped()
    msg.header.stamp = stamp
    msg.header.frame_id = frame
    msg.vector.x, msg.vector.y, msg.vector.z = (float(v) for v in vector)
    return msg


def imu_msg(stamp: Time, q_xyzw, w, a, frame: str = names.BASE_FRAME) -> Imu:
    msg = Imu()
    msg.header.stamp = stamp
    msg.header.frame_id = frame
    o = msg.orientation
    o.x, o.y, o.z, o.w = (float(v) for v in q_xyzw)
    v, f = msg.angular_velocity, msg.linear_acceleration
    v.x, v.y, v.z = (float(c) for c in w)
    f.x, f.y, f.z = (float(c) for c in a)
    return msg


def stamp_ns(msg) -> int:
    return conv.stamp_from_msg(msg.header.stamp)


@pytest.fixture
def make_node(ros_context):
    """Builds a node that lives for one hypothesis example (``with make_node() as node``)."""
    return functools.partial(node_under_test, IkTetherAllocatorNode, ros_context)


def _snapshot(node: IkTetherAllocatorNode) -> tuple:
    allocator_state = None if node.core.allocator is None else node.core.allocator._state
    return (
        node.core.last_allocation,
        node.core.last_good_setpoint,
        node.core.answered_ns,
        allocator_state,
        node.core.angular_velocity,
        node.core.specific_force,
        node.core.imu_t_ns,
    )


def _assert_node_sane(node: IkTetherAllocatorNode, published: dict[str, list]) -> None:
    commands = published[names.JOINT_COMMANDS]
    for msg in commands:
        assert_finite(msg)
        sample = conv.joint_state_from_msg(msg)  # 25 named joints, finite
        assert sample.velocity is not None
    stamps = [stamp_ns(m) for m in commands]
    assert stamps == sorted(stamps)  # never answered back in time
    for msg in published[names.DIAGNOSTICS]:
        assert_finite(msg)
    good = node.core.last_good_setpoint
    if good is not None:
        assert np.all(np.isfinite(good)) and np.all(good > 0.0)
        assert np.all(good <= node.core.max_setpoint_kg_m2)
    if node.core.angular_velocity is not None:
        assert np.all(np.abs(node.core.angular_velocity) <= MAX_BODY_RATE_RAD_S)
    a = node.core.last_allocation
    if a is not None:
        for field in ("joint_position", "joint_velocity", "radii_m", "achieved_inertia_kg_m2"):
            assert np.all(np.isfinite(getattr(a, field))), field
    assert_finite(conv.diagnostics_to_msg(0, [node.diagnostics_status()]))


@SETTINGS
@given(
    steps=st.lists(st.tuples(STAMP, st.one_of(PLAUSIBLE_INERTIA, ANY_VECTOR3), FRAME), max_size=8)
)
def test_setpoint_callback_survives_any_message(make_node, steps) -> None:
    with make_node(initialize_from_measured_inertia=False) as node:
        published = record_publications(node)
        clock = Clock()
        for spec, vector, frame in steps:
            msg = vector3_msg(clock.stamp(spec), vector, frame)
            before, rejected_before = _snapshot(node), total_rejections(node)
            answered_before = len(published[names.JOINT_COMMANDS])
            node._on_setpoint(msg)  # nothing may escape
            answered = len(published[names.JOINT_COMMANDS]) > answered_before
            v = np.array(vector)
            content_ok = (
                frame == names.BASE_FRAME
                and bool(np.all(np.isfinite(v)))
                and bool(np.all(v > 0.0))
                and bool(np.all(v <= node.core.max_setpoint_kg_m2))
            )
            event(f"answered: {answered}, content ok: {content_ok}")
            if not answered:  # a bad stamp: dropped, the node exactly as it was
                after = _snapshot(node)
                assert all(x is y for x, y in zip(after, before, strict=True))
                assert total_rejections(node) == rejected_before + 1
            else:
                assert stamp_ns(published[names.JOINT_COMMANDS][-1]) == stamp_ns(msg)
            if not content_ok:  # the last good setpoint is kept
                assert node.core.last_good_setpoint is before[1]
                assert total_rejections(node) == rejected_before + 1
            elif answered:
                np.testing.assert_array_equal(node.core.last_good_setpoint, v)
        _assert_node_sane(node, published)


UNIT_Q = st.sampled_from([(0.0, 0.0, 0.0, 1.0), (0.0, 0.0, math.sin(0.3), math.cos(0.3))])
SMALL_VECTOR3 = st.tuples(*[st.floats(-5.0, 5.0)] * 3)
IMU_CONTENT = st.one_of(
    st.tuples(UNIT_Q, SMALL_VECTOR3, SMALL_VECTOR3),
    st.tuples(
        st.one_of(UNIT_Q, st.tuples(ANY_FLOAT, ANY_FLOAT, ANY_FLOAT, ANY_FLOAT)),
        st.one_of(SMALL_VECTOR3, ANY_VECTOR3),
        ANY_VECTOR3,
    ),
)
INERTIA_CONTENT = st.one_of(PLAUSIBLE_INERTIA, ANY_VECTOR3)
STEP = st.one_of(
    st.tuples(st.just("setpoint"), STAMP, ANY_VECTOR3, FRAME),
    st.tuples(st.just("setpoint"), STAMP, PLAUSIBLE_INERTIA, FRAME),
    st.tuples(st.just("imu"), STAMP, IMU_CONTENT, FRAME),
    st.tuples(st.just("inertia"), STAMP, INERTIA_CONTENT, FRAME),
)


@SETTINGS
@given(steps=st.lists(STEP, max_size=12))
def test_any_sequence_of_imu_inertia_and_setpoints(make_node, steps) -> None:
    """All three callbacks interleaved: imu and inertia (the fallback answers inertia ticks
    while nothing publishes setpoints, as here) and setpoints."""
    with make_node() as node:
        published = record_publications(node)
        clock = Clock()
        for kind, spec, content, frame in steps:
            stamp = clock.stamp(spec)
            before, rejected_before = _snapshot(node), total_rejections(node)
            answered_before = len(published[names.JOINT_COMMANDS])
            if kind == "setpoint":
                node._on_setpoint(vector3_msg(stamp, content, frame))
            elif kind == "imu":
                q, w, a = content
                node._on_imu(imu_msg(stamp, q, w, a, frame))
                if node.core.angular_velocity is not before[4]:  # accepted: finite, plausible
                    assert frame == names.BASE_FRAME
                    np.testing.assert_array_equal(node.core.angular_velocity, w)
            else:
                node._on_inertia(vector3_msg(stamp, content, frame))
            rejected = total_rejections(node) > rejected_before
            answered = len(published[names.JOINT_COMMANDS]) > answered_before
            event(f"{kind}: {'rejected' if rejected else 'accepted'}{', answered' * answered}")
            if rejected and kind != "setpoint":
                # a rejected imu / inertia changes nothing and answers nothing
                assert all(x is y for x, y in zip(_snapshot(node), before, strict=True))
                assert len(published[names.JOINT_COMMANDS]) == answered_before
        _assert_node_sane(node, published)


# --- the known bugs --------------------------------------------------------------------
def _good_ticks(node: IkTetherAllocatorNode, n: int) -> None:
    for k in range(n):
        t = k * TICK_NS
        node._on_imu(imu_msg(conv.stamp_to_msg(t), (0, 0, 0, 1), (0.0, 1.0, 0.0), (0, 0, 0)))
        node._on_setpoint(vector3_msg(conv.stamp_to_msg(t), TARGET))
        node._on_inertia(vector3_msg(conv.stamp_to_msg(t), principal_inertia(MODEL, [2, 0.3, 0.2])))


def test_the_imu_accelerometer_tells_the_node_the_feet_hold_the_robot(make_node) -> None:
    """Standing on the Moon (g up, base frame) for the dwell lifts the free-fall limits;
    a reading of free fall restores them at once; a corrupt one changes nothing."""
    standing = (0.0, 0.0, 1.62)  # [m/s^2]
    with make_node() as node:
        dwell_ticks = round(node.config.supported_dwell_s * NS_PER_S / TICK_NS)
        for k in range(dwell_ticks + 1):
            stamp = conv.stamp_to_msg(k * TICK_NS)
            node._on_imu(imu_msg(stamp, (0, 0, 0, 1), (0.0, 0.0, 0.4), standing))
            node._on_setpoint(vector3_msg(stamp, TARGET))
        assert node.core.supported and node.core.last_allocation.supported
        stamp = conv.stamp_to_msg((dwell_ticks + 1) * TICK_NS)
        node._on_imu(imu_msg(stamp, (0, 0, 0, 1), (0.0, 0.0, 0.4), (0.0, 0.0, 1e6)))
        assert node.core.supported  # rejected: the last good reading stands
        node._on_imu(imu_msg(stamp, (0, 0, 0, 1), (0.0, 0.0, 0.4), (0.0, 0.0, 0.0)))
        node._on_setpoint(vector3_msg(stamp, TARGET))
        assert not node.core.supported and not node.core.last_allocation.supported


@pytest.mark.parametrize("value", [1e300, -1e300, 1.7976931348623157e308, 1e5, 0.0])
def test_huge_setpoint_is_rejected_and_answered_from_the_last_good(make_node, value: float) -> None:
    """1e300 on /splitter/inertia_setpoint crashed the node (AssertionError in the
    projection after an overflow); now it is rejected at the boundary, its tick answered."""
    with make_node(initialize_from_measured_inertia=False) as node:
        published = record_publications(node)
        _good_ticks(node, 3)
        good = node.core.last_good_setpoint
        node._on_setpoint(vector3_msg(conv.stamp_to_msg(3 * TICK_NS), [value] * 3))
        commands = published[names.JOINT_COMMANDS]
        assert [stamp_ns(m) for m in commands] == [0, TICK_NS, 2 * TICK_NS, 3 * TICK_NS]
        assert node.core.last_good_setpoint is good
        np.testing.assert_array_equal(node.core.last_allocation.requested_inertia_kg_m2, TARGET)
        assert rejection_counts(node)["setpoint"] == 1
        status = node.diagnostics_status()
        assert status.values["total_warnings_setpoint"] == 1
        assert status.values["setpoints_rejected"] == 1
        _assert_node_sane(node, published)


def test_tiny_positive_setpoint_is_legal_and_projected(make_node) -> None:
    with make_node(initialize_from_measured_inertia=False) as node:
        published = record_publications(node)
        _good_ticks(node, 1)
        node._on_setpoint(vector3_msg(conv.stamp_to_msg(TICK_NS), [1e-300] * 3))
        assert node.core.last_allocation.saturated
        assert total_rejections(node) == 0
        _assert_node_sane(node, published)


def test_projection_of_1e300_does_not_assert() -> None:
    """The core itself: the request is finite, so it has a nearest reachable point."""
    result = project_inertia(MODEL, [1e300] * 3)
    np.testing.assert_allclose(result.inertia_kg_m2, reachable_inertia_bounds(MODEL)[1])
    assert result.saturated


@pytest.mark.parametrize(
    ("label", "stamp"),
    [
        ("zero", Time()),
        ("backwards", conv.stamp_to_msg(2 * TICK_NS)),
        ("far ahead", Time(sec=2_000_000_000)),
        ("just beyond the lead", conv.stamp_to_msg(5 * TICK_NS + MAX_STAMP_LEAD_NS + 1)),
        ("nanosec out of range", Time(sec=0, nanosec=4_000_000_000)),
        ("negative", Time(sec=-1)),
    ],
)
def test_bad_stamp_is_rejected_and_never_resets_the_allocator(
    make_node, label: str, stamp: Time
) -> None:
    """A setpoint stamped 0 once time advanced used to "restart the allocator from the
    last radii"; a bad stamp is now a rejected input: nothing answered, nothing reset."""
    with make_node(initialize_from_measured_inertia=False) as node:
        published = record_publications(node)
        _good_ticks(node, 6)
        before = _snapshot(node)
        state = node.core.allocator._state
        node._on_setpoint(vector3_msg(stamp, TARGET))
        node._on_imu(imu_msg(stamp, (0, 0, 0, 1), (0.0, 9.0, 0.0), (0, 0, 0)))
        node._on_inertia(vector3_msg(stamp, TARGET))
        assert all(x is y for x, y in zip(_snapshot(node), before, strict=True)), label
        assert node.core.allocator._state is state
        assert len(published[names.JOINT_COMMANDS]) == 6
        assert total_rejections(node) == 3
        # the next tick continues the reference where it was: q6 = q5 + v5 dt
        node._on_setpoint(vector3_msg(conv.stamp_to_msg(6 * TICK_NS), TARGET))
        q5, q6 = (conv.joint_state_from_msg(m) for m in published[names.JOINT_COMMANDS][-2:])
        np.testing.assert_allclose(q6.position, q5.position + q5.velocity * 0.01, atol=1e-12)
        _assert_node_sane(node, published)


def test_a_repeated_tick_is_recomputed_not_rejected(make_node) -> None:
    with make_node(initialize_from_measured_inertia=False) as node:
        published = record_publications(node)
        _good_ticks(node, 3)
        node._on_setpoint(vector3_msg(conv.stamp_to_msg(2 * TICK_NS), TARGET * 1.01))
        assert [stamp_ns(m) for m in published[names.JOINT_COMMANDS]][-2:] == [2 * TICK_NS] * 2
        assert total_rejections(node) == 0
