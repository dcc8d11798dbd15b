"""Conversions round-trip through CDR serialization and reject bad input."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message

from splitter_msgs_py import conversions as conv
from splitter_msgs_py import names
from splitter_msgs_py.core.stamps import StampGate

RNG = np.random.default_rng(7)


def cdr_round_trip(msg):
    return deserialize_message(serialize_message(msg), type(msg))


def random_quaternion() -> np.ndarray:
    q = RNG.normal(size=4)
    return q / np.linalg.norm(q)


def test_stamp_is_exact_in_nanoseconds() -> None:
    for t_ns in (0, 5_000_000, 1_999_999_999, 123_456_789_012):
        assert conv.stamp_from_msg(cdr_round_trip(conv.stamp_to_msg(t_ns))) == t_ns
    assert conv.stamp_from_msg(conv.clock_to_msg(7).clock) == 7
    with pytest.raises(conv.MessageValidationError):
        conv.stamp_to_msg(-1)


def test_imu_round_trip() -> None:
    q, w, a = random_quaternion(), RNG.normal(size=3), RNG.normal(size=3)
    sample = conv.imu_from_msg(cdr_round_trip(conv.imu_to_msg(15_000_000, q, w, a)))
    assert sample.t_ns == 15_000_000
    np.testing.assert_allclose(sample.orientation_wxyz, q, atol=1e-15)
    np.testing.assert_array_equal(sample.angular_velocity_rad_s, w)
    np.testing.assert_array_equal(sample.linear_acceleration_m_s2, a)


def test_odom_round_trip_rotates_velocity_into_base_and_back() -> None:
    q, p, v, w = random_quaternion(), RNG.normal(size=3), RNG.normal(size=3), RNG.normal(size=3)
    msg = cdr_round_trip(conv.odom_to_msg(10, p, q, v, w))
    assert (msg.header.frame_id, msg.child_frame_id) == (names.WORLD_FRAME, names.BASE_FRAME)
    base_v = np.array(
        [msg.twist.twist.linear.x, msg.twist.twist.linear.y, msg.twist.twist.linear.z]
    )
    np.testing.assert_allclose(conv.quaternion_to_matrix(q) @ base_v, v, atol=1e-12)
    sample = conv.odom_from_msg(msg)
    np.testing.assert_allclose(sample.velocity_world_m_s, v, atol=1e-12)
    np.testing.assert_array_equal(sample.position_m, p)
    np.testing.assert_array_equal(sample.angular_velocity_rad_s, w)


def test_vector3_wrench_twist_pose_round_trips() -> None:
    v = conv.vector3_from_msg(cdr_round_trip(conv.vector3_to_msg(3, [0.48, 141.36, 141.36])))
    assert v.t_ns == 3 and v.frame_id == names.BASE_FRAME
    np.testing.assert_array_equal(v.vector, [0.48, 141.36, 141.36])
    wr = conv.wrench_from_msg(cdr_round_trip(conv.wrench_to_msg(4, [40, 0, 40], [0, 1, 0])))
    np.testing.assert_array_equal(wr.force_n, [40, 0, 40])
    np.testing.assert_array_equal(wr.torque_nm, [0, 1, 0])
    t_ns, w = conv.twist_from_msg(cdr_round_trip(conv.twist_to_msg(5, [0.0, 1.0, 0.0])))
    assert t_ns == 5
    np.testing.assert_array_equal(w, [0.0, 1.0, 0.0])
    q = random_quaternion()
    t_ns, q_back, p = conv.pose_from_msg(cdr_round_trip(conv.pose_to_msg(6, q, [1, 2, 3])))
    np.testing.assert_allclose(q_back, q, atol=1e-15)
    np.testing.assert_array_equal(p, [1, 2, 3])


def test_joint_state_round_trip_and_reordering() -> None:
    pos, vel = RNG.normal(size=25), RNG.normal(size=25)
    msg = cdr_round_trip(conv.joint_state_to_msg(9, pos, vel))
    assert list(msg.name) == list(names.JOINT_NAMES)
    sample = conv.joint_state_from_msg(msg)
    np.testing.assert_array_equal(sample.position, pos)
    np.testing.assert_array_equal(sample.velocity, vel)
    assert sample.effort is None
    # a publisher may order joints differently
    msg.name = list(reversed(msg.name))
    msg.position = list(reversed(msg.position))
    msg.velocity = []
    sample = conv.joint_state_from_msg(msg)
    np.testing.assert_array_equal(sample.position, pos)
    assert sample.velocity is None


@pytest.mark.parametrize(
    ("mutate", "match"),
    [
        (lambda m: m.name.__setitem__(0, "no_such_joint"), "unknown joints"),
        (lambda m: m.name.__setitem__(1, m.name[0]), "duplicate"),
        (lambda m: (m.name.pop(), m.position.pop()), "missing"),
        (lambda m: m.position.__setitem__(3, math.nan), "non-finite"),
        (lambda m: m.position.__setitem__(3, math.inf), "non-finite"),
        (lambda m: m.velocity.pop(), "velocity"),
    ],
)
def test_joint_state_rejects_bad_messages(mutate, match: str) -> None:
    msg = conv.joint_state_to_msg(0, np.zeros(25), np.zeros(25))
    msg.name = list(msg.name)
    msg.position = list(msg.position)
    msg.velocity = list(msg.velocity)
    mutate(msg)
    with pytest.raises(conv.MessageValidationError, match=match):
        conv.joint_state_from_msg(msg)


def test_quaternion_normalized_within_tolerance_rejected_beyond() -> None:
    msg = conv.imu_to_msg(0, [1, 0, 0, 0], [0, 0, 0], [0, 0, 0])
    msg.orientation.w = 1.0005
    np.testing.assert_allclose(np.linalg.norm(conv.imu_from_msg(msg).orientation_wxyz), 1.0)
    msg.orientation.w = 1.1
    with pytest.raises(conv.MessageValidationError, match="norm"):
        conv.imu_from_msg(msg)
    msg.orientation.w = math.nan
    with pytest.raises(conv.MessageValidationError, match="non-finite"):
        conv.imu_from_msg(msg)


def test_builders_refuse_to_publish_nan() -> None:
    with pytest.raises(conv.MessageValidationError):
        conv.vector3_to_msg(0, [math.nan, 0, 0])
    with pytest.raises(conv.MessageValidationError):
        conv.joint_state_to_msg(0, np.zeros(24))
    with pytest.raises(conv.MessageValidationError):
        conv.diagnostics_to_msg(0, [conv.DiagnosticStatusSample("x", 0, "", {"a": math.inf})])


def test_diagnostics_round_trip() -> None:
    statuses = [
        conv.DiagnosticStatusSample(
            "simulator: energy", 0, "ok", {"energy_j": 114.6, "steps": 3, "slack": False}
        ),
        conv.DiagnosticStatusSample("mpc: solver", 1, "late", {"status": "Maximum_Iterations"}),
    ]
    back = conv.diagnostics_from_msg(cdr_round_trip(conv.diagnostics_to_msg(1, statuses)))
    assert back[0].values == {"energy_j": 114.6, "steps": 3.0, "slack": False}
    assert back[1].level == 1 and back[1].values["status"] == "Maximum_Iterations"


def test_every_topic_has_a_message_class() -> None:
    for topic, type_name in names.TOPIC_TYPES.items():
        cls = conv.TOPIC_MESSAGE_CLASSES[topic]
        assert type_name.endswith(cls.__name__)
    with pytest.raises(ValueError):
        conv.message_class("not_a_type")


def test_checked_stamp_rejects_negative_and_unnormalized_stamps() -> None:
    from builtin_interfaces.msg import Time

    assert conv.checked_stamp_from_msg(Time(sec=3, nanosec=999_999_999)) == 3_999_999_999
    assert conv.checked_stamp_from_msg(Time()) == 0
    for bad in (Time(sec=-1), Time(sec=0, nanosec=1_000_000_000), Time(sec=1, nanosec=2**32 - 1)):
        with pytest.raises(conv.MessageValidationError, match=r"header\.stamp"):
            conv.checked_stamp_from_msg(bad)


def test_stamp_gate_per_topic_order_and_lead() -> None:
    gate = StampGate(max_lead_ns=100)
    assert gate.latest_ns is None
    gate.accept("a", gate.check("a", 10_000))  # the first stamp has no reference
    gate.accept("a", gate.check("a", 10_000))  # a repeat is fine
    with pytest.raises(conv.MessageValidationError, match="earlier"):
        gate.check("a", 0)  # zero once time advanced
    with pytest.raises(conv.MessageValidationError, match="earlier"):
        gate.check("a", 9_999)
    gate.accept("b", gate.check("b", 5))  # another topic has its own order ...
    with pytest.raises(conv.MessageValidationError, match="ahead"):
        gate.check("b", 10_101)  # ... but the node's time is shared
    with pytest.raises(conv.MessageValidationError, match="ahead"):
        gate.check("c", 20_000, clock_ns=10)  # a fresh topic: the newest stamp counts
    gate.check("c", 20_000, clock_ns=19_950)  # a later clock moves the node's time
    with pytest.raises(conv.MessageValidationError, match="negative"):
        gate.check("c", -1)
    assert (gate.last_ns("a"), gate.last_ns("b"), gate.last_ns("c")) == (10_000, 5, None)
    assert gate.latest_ns == 10_000
    with pytest.raises(ValueError):
        StampGate(-1)


def test_stamp_gate_reads_a_clock_function_only_when_the_newest_stamp_cannot_decide() -> None:
    gate = StampGate(max_lead_ns=100)
    reads: list[int] = []

    def clock(value: int | None) -> Callable[[], int | None]:
        def read() -> int | None:
            reads.append(1)
            return value

        return read

    gate.accept("a", gate.check("a", 1_000, clock(None)))  # nothing to compare with
    assert len(reads) == 1
    gate.accept("a", gate.check("a", 1_100, clock(0)))  # within the lead of the newest
    assert len(reads) == 1
    with pytest.raises(conv.MessageValidationError, match="ahead"):
        gate.check("b", 1_201, clock(1_000))  # beyond both: refused, as with the value
    assert len(reads) == 2
    assert gate.check("b", 1_201, clock(1_150)) == 1_201  # a later clock admits it
    assert len(reads) == 3
    gate.accept("b", 1_201)
    assert gate.latest_ns == 1_201  # kept as the newest accepted stamp


def test_huge_numbers_are_rejected_not_overflowed() -> None:
    q = random_quaternion()
    msg = conv.odom_to_msg(0, [0, 0, 0], q, [0, 0, 0], [0, 0, 0])
    msg.twist.twist.linear.x = msg.twist.twist.linear.y = 1.7e308
    msg.twist.twist.linear.z = -1.7e308
    msg.pose.pose.orientation.w, msg.pose.pose.orientation.x = 0.6, 0.8  # rotates x into y
    msg.pose.pose.orientation.y = msg.pose.pose.orientation.z = 0.0
    with np.errstate(all="raise"), pytest.raises(conv.MessageValidationError, match="twist"):
        conv.odom_from_msg(msg)
    with np.errstate(all="raise"), pytest.raises(conv.MessageValidationError, match="quaternion"):
        conv.unit_quaternion([1e300, 0.0, 0.0, 1e300])
    with pytest.raises(conv.MessageValidationError, match="velocity"):
        conv.odom_to_msg(0, [0, 0, 0], [0.6, 0.8, 0, 0], [0, 1.7e308, 1.7e308], [0, 0, 0])


def test_joint_health_round_trip_and_refusals() -> None:
    from types import SimpleNamespace

    reachable = SimpleNamespace(
        radius_min_m=np.array([0.5, 0.2, 0.107]), radius_max_m=np.array([3.0, 0.31, 0.397])
    )
    knee = names.JOINT_INDEX["hemi_a_y_pos_knee"]
    status = conv.joint_health_status({knee: "stuck"}, reachable, "ik_tether_allocator")
    msg = conv.diagnostics_to_msg(7_000_000, [status])
    msg = deserialize_message(serialize_message(msg), type(msg))
    health = conv.joint_health_from_msg(msg)
    assert health.symptoms == {"hemi_a_y_pos_knee": "stuck"}
    assert np.array_equal(health.radius_min_m, reachable.radius_min_m)
    assert np.array_equal(health.radius_max_m, reachable.radius_max_m)
    for key, value in (
        ("radius_min_y_m", "nan"),
        ("radius_max_x_m", "0.1"),  # below its min
        ("elbow", "stuck"),
    ):
        bad = conv.diagnostics_to_msg(7_000_000, [status])
        bad.status[0].values = [kv for kv in bad.status[0].values if kv.key != key]
        bad.status[0].values.append(type(bad.status[0].values[0])(key=key, value=value))
        with pytest.raises(conv.MessageValidationError):
            conv.joint_health_from_msg(bad)
    with pytest.raises(conv.MessageValidationError, match="1 status"):
        conv.joint_health_from_msg(conv.diagnostics_to_msg(0, []))
