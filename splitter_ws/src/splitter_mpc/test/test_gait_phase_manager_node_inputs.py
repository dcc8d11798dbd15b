"""gait_phase_manager: every subscription callback survives any message (property tests).

The node is built in-process and its callbacks (IMU, both rangefinders, both leg load
cells, joint states, inertia) are called directly, interleaved with complete good
ticks, with messages whose contents hypothesis draws: floats of any magnitude, arrays
of any length, any joint names and frame ids, stamps of any value (0, backwards, far
ahead, out-of-range fields). Nothing may escape a callback; a message rejected for
its stamp is filed under no tick and leaves the last good message of its topic; one
rejected for its contents leaves it too; what is certainly bad (a wrong frame, a
non-finite or implausible number, a NaN or negative range) is rejected, what is
certainly good is taken; everything the node publishes is finite.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Collection

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Vector3Stamped
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu, Range

from splitter_model.actuators import TETHER_INDEX
from splitter_model.rotations import quaternion_to_matrix
from splitter_model.sensors import RANGE_FIELD_OF_VIEW_RAD, RANGE_MAX_M, RANGE_MIN_M
from splitter_mpc.core.gait import GaitPhase
from splitter_mpc.core.gait_tick import (
    MAX_BODY_RATE_RAD_S,
    MAX_LEG_FORCE_N,
    MAX_SPECIFIC_FORCE_M_S2,
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
    publishers_on,
    wrench_msg,
)

# An overflow inside a callback means an implausible number got past validation.
pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")

MS = 1_000_000  # [ns]
TICK_NS = 10 * MS
NS_PER_S = 1_000_000_000
G_M_S2 = 1.62  # [m/s^2] the moon's gravity, known to the gait (parameter gravity_m_s2)
PITCH_RAD = math.radians(10.0)
Q_BODY_WXYZ = (math.cos(PITCH_RAD / 2), 0.0, math.sin(PITCH_RAD / 2), 0.0)
# Standing still: the accelerometer reads gravity alone, in the (pitched) base frame.
STANDING_SPECIFIC_FORCE = tuple(
    (quaternion_to_matrix(np.array(Q_BODY_WXYZ)).T @ np.array([0.0, 0.0, G_M_S2])).tolist()
)
BODY_RATE = (0.5, -0.5, 0.5)  # [rad/s] of the good ticks
RANGES_M = (0.25, 0.7)  # [m] hemi a, b of the good ticks
LEG_FORCE_N = (0.0, 0.0, 20.0)  # [N] base frame, each hemi in stance on the good ticks
INERTIA_KG_M2 = (0.48, 141.36, 141.36)
RANGE_LIMITS = (RANGE_MIN_M, RANGE_MAX_M, RANGE_FIELD_OF_VIEW_RAD)
PLAN = [
    Parameter("jump_times_s", value=[0.02]),
    Parameter("jump_forces_n", value=[40.0, 0.0, 40.0]),
    Parameter("jump_durations_s", value=[0.03]),
    Parameter("jump_hemis", value=["auto"]),
    Parameter("landed_dwell_s", value=0.02),
    # the synthetic body stands pitched 10 deg: no downhill scaling of the plan's push
    Parameter("jump_level_slope_deg", value=90.0),
    Parameter("w_ref_rad_s", value=[0.0, 1.0, 0.0]),
    Parameter("attitude_reference", value="momentum_aligned"),  # subscribes to the inertia
    Parameter("gravity_m_s2", value=G_M_S2),
]
SMALL_VECTOR3 = st.tuples(*[st.floats(-2.0, 2.0)] * 3)
FRAME = st.one_of(
    st.sampled_from([names.WORLD_FRAME, names.BASE_FRAME, *names.HEMI_FRAMES, ""]), ANY_TEXT
)
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
SPECIFIC_FORCE = st.tuples(*[st.floats(-20.0, 20.0)] * 3)
# IMU content: (frame id, orientation (w, x, y, z), gyro, accelerometer)
GOOD_IMU = st.tuples(st.just(names.BASE_FRAME), st.just(Q_BODY_WXYZ), SMALL_VECTOR3, SPECIFIC_FORCE)
IMU = st.tuples(
    st.one_of(st.just(names.BASE_FRAME), FRAME),
    QUATERNION,
    st.one_of(SMALL_VECTOR3, ANY_VECTOR3),
    st.one_of(SPECIFIC_FORCE, ANY_VECTOR3),
)
# sensor_msgs/Range's numbers are float32: anything in its range, the infinities and NaN.
FLOAT32_SPECIALS = (math.nan, math.inf, -math.inf, 3.4e38, -3.4e38, 1e-45, 0.0, -0.0, -1e-300)
ANY_FLOAT32 = st.one_of(st.floats(-3.4e38, 3.4e38), st.sampled_from(FLOAT32_SPECIALS))
# range content: (topic, frame id, range, (min range, max range, field of view))
GOOD_RANGE = st.sampled_from(names.RANGES).flatmap(
    lambda topic: st.tuples(
        st.just(topic),
        st.just(names.HEMI_FRAMES[names.RANGES.index(topic)]),
        st.one_of(st.floats(RANGE_MIN_M, RANGE_MAX_M), st.sampled_from([math.inf, -math.inf])),
        st.just(RANGE_LIMITS),
    )
)
RANGE = st.tuples(
    st.sampled_from(names.RANGES),
    st.one_of(st.sampled_from(names.HEMI_FRAMES), FRAME),
    ANY_FLOAT32,
    st.one_of(st.just(RANGE_LIMITS), st.tuples(ANY_FLOAT32, ANY_FLOAT32, ANY_FLOAT32)),
)
# leg load cell content: (topic, frame id, force, torque)
LEG_FORCE = st.tuples(*[st.floats(-60.0, 60.0)] * 3)
GOOD_LEG = st.tuples(
    st.sampled_from(names.LEG_FORCES), st.just(names.BASE_FRAME), LEG_FORCE, SMALL_VECTOR3
)
LEG = st.tuples(
    st.sampled_from(names.LEG_FORCES),
    st.one_of(st.just(names.BASE_FRAME), FRAME),
    st.one_of(LEG_FORCE, ANY_VECTOR3),
    st.one_of(SMALL_VECTOR3, ANY_VECTOR3),
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
    st.tuples(st.just(names.IMU), STAMP, st.one_of(GOOD_IMU, IMU)),
    st.tuples(st.just("range"), STAMP, st.one_of(GOOD_RANGE, RANGE)),
    st.tuples(st.just("leg force"), STAMP, st.one_of(GOOD_LEG, LEG)),
    st.tuples(st.just(names.JOINT_STATES), STAMP, JOINTS),
    st.tuples(st.just(names.INERTIA), STAMP, INERTIA),
)
SETTINGS = settings(
    max_examples=100,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)


# --- messages -------------------------------------------------------------------------------
def imu_msg(stamp: Time, content: tuple) -> Imu:
    """``content``: (frame id, orientation (w, x, y, z), gyro, accelerometer), unchecked."""
    frame, q_wxyz, rate, specific_force = content
    msg = Imu()
    msg.header.stamp = stamp
    msg.header.frame_id = frame
    o, w, f = msg.orientation, msg.angular_velocity, msg.linear_acceleration
    o.w, o.x, o.y, o.z = (float(v) for v in q_wxyz)
    w.x, w.y, w.z = (float(v) for v in rate)
    f.x, f.y, f.z = (float(v) for v in specific_force)
    return msg


def range_msg(stamp: Time, content: tuple) -> Range:
    """``content``: (topic, frame id, range, (min range, max range, field of view)), unchecked."""
    _topic, frame, value, (min_range, max_range, field_of_view) = content
    msg = Range()
    msg.header.stamp = stamp
    msg.header.frame_id = frame
    msg.radiation_type = Range.INFRARED
    msg.min_range, msg.max_range = float(min_range), float(max_range)
    msg.field_of_view = float(field_of_view)
    msg.range = float(value)
    return msg


def vector3_msg(stamp: Time, frame: str, vector) -> Vector3Stamped:
    msg = Vector3Stamped()
    msg.header.stamp = stamp
    msg.header.frame_id = frame
    msg.vector.x, msg.vector.y, msg.vector.z = (float(v) for v in vector)
    return msg


def good_input(topic: str, t_ns: int) -> object:
    """The valid message of ``topic`` stamped ``t_ns``, as the simulator publishes it: the
    robot standing on both hemis, spinning slowly."""
    if topic == names.IMU:
        return conv.imu_to_msg(t_ns, Q_BODY_WXYZ, BODY_RATE, STANDING_SPECIFIC_FORCE)
    if topic in names.RANGES:
        i = names.RANGES.index(topic)
        return conv.range_to_msg(
            t_ns,
            RANGES_M[i],
            names.HEMI_FRAMES[i],
            min_range_m=RANGE_MIN_M,
            max_range_m=RANGE_MAX_M,
            field_of_view_rad=RANGE_FIELD_OF_VIEW_RAD,
        )
    if topic in names.LEG_FORCES:
        return conv.wrench_to_msg(t_ns, LEG_FORCE_N, (0.0, 0.0, 0.0), names.BASE_FRAME)
    if topic == names.JOINT_STATES:
        joints = np.zeros(names.N_JOINTS)
        joints[TETHER_INDEX] = 2.8
        return conv.joint_state_to_msg(t_ns, joints)
    assert topic == names.INERTIA, topic
    return conv.vector3_to_msg(t_ns, INERTIA_KG_M2, names.BASE_FRAME)


def send_good_tick(node: GaitPhaseManagerNode, t_ns: int, *, without: Collection[str] = ()) -> None:
    """A complete, valid set of the tick's inputs (but those of the topics ``without``)."""
    for topic in node.tick.ticks.inputs:
        if topic not in without:
            node._on_input(topic, good_input(topic, t_ns))


# --- what must be rejected, what must be taken -------------------------------------------------
def _finite(*vectors) -> bool:
    return all(math.isfinite(float(v)) for vector in vectors for v in vector)


def _within(vector, limit: float) -> bool:
    return all(abs(float(v)) <= limit for v in vector)


def verdict(kind: str, content: tuple) -> str | None:
    """'reject' or 'accept' where the contents decide it for sure (stamp aside), else None.

    IMU and leg load cells: frame ``base`` only, every number finite and within the
    plausibility limits; rangefinders: NaN and negative finite ranges are refused,
    +-inf (REP 117) and a distance within the sensor's range taken (in its own frame).
    """
    if kind == names.IMU:
        frame, q_wxyz, rate, specific_force = content
        if (
            frame != names.BASE_FRAME
            or not _finite(q_wxyz, rate, specific_force)
            or not _within(rate, MAX_BODY_RATE_RAD_S)
            or not _within(specific_force, MAX_SPECIFIC_FORCE_M_S2)
        ):
            return "reject"
        return "accept" if tuple(q_wxyz) == Q_BODY_WXYZ else None
    if kind == "leg force":
        _topic, frame, force, torque = content
        if frame != names.BASE_FRAME or not _finite(force, torque):
            return "reject"
        return "accept" if _within(force, MAX_LEG_FORCE_N) else "reject"
    if kind == "range":
        topic, frame, value, _limits = content
        own_frame = frame == names.HEMI_FRAMES[names.RANGES.index(topic)]
        if not own_frame or math.isnan(value) or (math.isfinite(value) and value < 0.0):
            return "reject"
        if math.isfinite(value) and value > RANGE_MAX_M:  # the sensor would say +inf
            return "reject"
        return "accept" if math.isinf(value) or RANGE_MIN_M <= value else None
    return None


# --- the example's clock ------------------------------------------------------------------------
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
    if names.IMU in good:
        imu = good[names.IMU]
        assert abs(float(np.linalg.norm(imu.orientation_wxyz)) - 1.0) < 1e-9
        assert np.all(np.abs(imu.angular_velocity_rad_s) <= MAX_BODY_RATE_RAD_S)
        assert np.all(np.abs(imu.specific_force_m_s2) <= MAX_SPECIFIC_FORCE_M_S2)
    for topic in names.RANGES:
        if topic in good:
            distance = good[topic]
            assert not math.isnan(distance)
            assert distance >= 0.0 or distance == -math.inf
    for topic in names.LEG_FORCES:
        if topic in good:
            assert np.shape(good[topic]) == (3,)
            assert np.all(np.abs(good[topic]) <= MAX_LEG_FORCE_N)
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


def _message(kind: str, stamp: Time, content: tuple) -> tuple[str, object]:
    """(topic, message) of a drawn step."""
    if kind == names.IMU:
        return names.IMU, imu_msg(stamp, content)
    if kind == "range":
        return content[0], range_msg(stamp, content)
    if kind == "leg force":
        return content[0], wrench_msg(stamp, *content[1:])
    if kind == names.JOINT_STATES:
        return names.JOINT_STATES, joint_state_msg(stamp, *content)
    return names.INERTIA, vector3_msg(stamp, *content)


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
            topic, msg = _message(kind, stamp, content)
            acceptable = stamps.acceptable(topic, stamp)
            last_good, pending = node.tick.ticks.last_good.get(topic), _pending(node)
            rejected_before = rejections(node)
            node._on_input(topic, msg)
            rejected = rejections(node) > rejected_before
            event(f"{kind}: {'rejected' if rejected else 'accepted'}")
            if not acceptable:  # filed under no tick, the last good message kept
                assert rejected
                assert node.tick.ticks.last_good.get(topic) is last_good
                assert _same_pending(_pending(node), pending)
                continue
            stamps.accepted(topic, conv.stamp_from_msg(stamp))
            expected = verdict(kind, content)
            if expected is not None:
                assert rejected == (expected == "reject"), (kind, content)
            if rejected:
                assert node.tick.ticks.last_good.get(topic) is last_good
            else:  # replaced (a number equal to the last may be the same float object)
                now = node.tick.ticks.last_good[topic]
                assert now is not last_good or isinstance(now, float)
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
        node._on_input(names.IMU, conv.imu_to_msg(0, Q_BODY_WXYZ, (3.0, 0.0, 0.0), (5.0, 0, 0)))
        assert all(node.tick.ticks.last_good[topic] is sample for topic, sample in good.items())
        assert rejection_counts(node) == {names.IMU: 1}
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


# --- contents: rejected, the tick answered from the last good message ----------------------
def _imu(mutate):
    def make(t_ns: int) -> Imu:
        msg = good_input(names.IMU, t_ns)
        mutate(msg)
        return msg

    return make


def _leg(frame: str, force) -> object:
    return lambda t_ns: wrench_msg(conv.stamp_to_msg(t_ns), frame, force, (0.0, 0.0, 0.0))


def _range_frame(frame: str) -> object:
    def make(t_ns: int) -> Range:
        msg = good_input(names.RANGE_A, t_ns)
        msg.header.frame_id = frame
        return msg

    return make


def _range(value: float) -> object:
    def make(t_ns: int) -> Range:
        msg = good_input(names.RANGE_A, t_ns)
        msg.range = value
        return msg

    return make


IMPLAUSIBLE = [
    (names.IMU, "rate 1e300", _imu(lambda m: setattr(m.angular_velocity, "y", 1e300))),
    (names.IMU, "rate beyond the limit", _imu(lambda m: setattr(m.angular_velocity, "x", -2e3))),
    (names.IMU, "rate NaN", _imu(lambda m: setattr(m.angular_velocity, "z", math.nan))),
    (names.IMU, "specific force 1e300", _imu(lambda m: setattr(m.linear_acceleration, "z", 1e300))),
    (
        names.IMU,
        "max float specific force",
        _imu(lambda m: setattr(m.linear_acceleration, "x", -1.7976931348623157e308)),
    ),
    (
        names.IMU,
        "specific force inf",
        _imu(lambda m: setattr(m.linear_acceleration, "y", math.inf)),
    ),
    (names.IMU, "non-unit quaternion", _imu(lambda m: setattr(m.orientation, "w", 2.0))),
    (names.IMU, "world frame", _imu(lambda m: setattr(m.header, "frame_id", names.WORLD_FRAME))),
    (names.IMU, "hemi frame", _imu(lambda m: setattr(m.header, "frame_id", "hemi_a"))),
    (names.IMU, "no frame", _imu(lambda m: setattr(m.header, "frame_id", ""))),
    (names.LEG_FORCE_A, "force 1e300", _leg(names.BASE_FRAME, (0.0, 0.0, 1e300))),
    (names.LEG_FORCE_B, "max float force", _leg(names.BASE_FRAME, (-1.7976931348623157e308, 0, 0))),
    (names.LEG_FORCE_A, "force beyond the limit", _leg(names.BASE_FRAME, (0.0, 2e7, 0.0))),
    (names.LEG_FORCE_B, "force NaN", _leg(names.BASE_FRAME, (0.0, 0.0, math.nan))),
    (names.LEG_FORCE_A, "world frame", _leg(names.WORLD_FRAME, LEG_FORCE_N)),
    (names.LEG_FORCE_B, "hemi frame", _leg("hemi_b", LEG_FORCE_N)),
    (names.RANGE_A, "range NaN", _range(math.nan)),
    (names.RANGE_A, "range negative", _range(-0.3)),
    (names.RANGE_A, "range -3.4e38", _range(-3.4e38)),
    (names.RANGE_A, "range 1e30 (beyond the sensor)", _range(1e30)),
    (names.RANGE_A, "range 1000 m (beyond the sensor)", _range(1000.0)),
    (names.RANGE_A, "range in hemi b's frame", _range_frame(names.HEMI_FRAMES[1])),
]


@pytest.mark.parametrize(
    ("topic", "label", "make_bad"), IMPLAUSIBLE, ids=[f"{t} {label}" for t, label, _ in IMPLAUSIBLE]
)
def test_implausible_input_is_rejected_and_its_tick_answered(
    make_node, topic, label, make_bad
) -> None:
    with make_node() as node:
        published = record_publications(node)
        send_good_tick(node, 0)
        good = node.tick.ticks.last_good[topic]
        node._on_input(topic, make_bad(TICK_NS))
        assert node.tick.ticks.last_good[topic] is good, label
        assert len(published[names.JUMP_COMMAND]) == 1  # tick 10 ms waits for the others
        send_good_tick(node, TICK_NS, without=[topic])
        assert len(published[names.JUMP_COMMAND]) == 2  # answered from the last good message
        assert node.tick.last_output.t_ns == TICK_NS  # by the phase machine: no zero answer
        assert rejection_counts(node) == {topic: 1}
        assert node.tick.stale_ticks == 1
        _assert_published_sane(published)


@pytest.mark.parametrize(
    ("value", "expected"),
    [(math.inf, math.inf), (-math.inf, -math.inf), (RANGE_MIN_M, RANGE_MIN_M), (7.5, 7.5)],
)
def test_a_distance_and_no_return_are_taken(make_node, value: float, expected: float) -> None:
    """REP 117: +inf (no return) and -inf (too close) are readings, not errors."""
    with make_node() as node:
        published = record_publications(node)
        send_good_tick(node, 0)
        node._on_input(names.RANGE_A, _range(value)(TICK_NS))
        assert node.tick.ticks.last_good[names.RANGE_A] == expected
        send_good_tick(node, TICK_NS, without=[names.RANGE_A])
        assert len(published[names.JUMP_COMMAND]) == 2
        assert rejection_counts(node) == {}
        assert node.tick.stale_ticks == 0
        _assert_published_sane(published)


def test_stance_comes_from_the_leg_load_cells(make_node) -> None:
    """A hemi is in stance when its legs push harder than ``stance_force_threshold_n``
    (2 N), whatever the direction of the push in the base frame: the due jump ('auto')
    pushes through the hemi in stance, and waits while none is."""
    with make_node() as node:
        published = record_publications(node)
        send_good_tick(node, 0)
        send_good_tick(node, TICK_NS)
        assert node.tick.last_output.stance == (True, True)
        for k, forces in (
            (2, ((1.0, 0.0, 1.0), (0.0, 0.0, 1.9))),
            (3, ((1.0, 0, 1.0), (-3, 0, 0))),
        ):
            stamp = conv.stamp_to_msg(k * TICK_NS)  # the jump is due from 20 ms on
            for topic, force in zip(names.LEG_FORCES, forces, strict=True):
                node._on_input(topic, wrench_msg(stamp, names.BASE_FRAME, force, (0.0, 0.0, 0.0)))
            send_good_tick(node, k * TICK_NS, without=names.LEG_FORCES)
            assert node.tick.last_output.jump_waiting == (k == 2)
        commands = [conv.wrench_from_msg(m).force_n for m in published[names.JUMP_COMMAND]]
        assert len(commands) == 4
        assert not np.any(commands[:3])  # |(1, 0, 1)| = 1.41 N and 1.9 N: no stance, no thrust
        np.testing.assert_allclose(commands[3], (40.0, 0.0, 40.0))  # |(-3, 0, 0)| = 3 N: b
        assert node.tick.last_output.stance == (False, True)
        assert node.tick.last_output.pushing_hemi == "b"
        assert rejection_counts(node) == {}
        _assert_published_sane(published)


def test_a_refused_input_answers_no_tick_while_a_stranger_publishes_on_its_topic(
    make_node, ros_context
) -> None:
    """Two IMU publishers: a refused IMU may be the stranger's, stamped at a tick whose
    real IMU is still on its way; the tick waits for it instead of using the last good."""
    with make_node() as node, publishers_on(ros_context, node, {names.IMU: Imu}):
        published = record_publications(node)
        send_good_tick(node, 0)
        bad = _imu(lambda m: setattr(m.angular_velocity, "z", math.nan))
        send_good_tick(node, TICK_NS, without=[names.IMU])
        node._on_input(names.IMU, bad(TICK_NS))
        assert len(published[names.JUMP_COMMAND]) == 1  # still waiting for the IMU
        node._on_input(names.IMU, good_input(names.IMU, TICK_NS))
        assert len(published[names.JUMP_COMMAND]) == 2
        assert rejection_counts(node) == {names.IMU: 1}
        assert node.tick.stale_ticks == 0
