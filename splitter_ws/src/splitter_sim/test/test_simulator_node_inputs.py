"""simulator: both command callbacks survive any message (property tests).

The node is built in-process (never spun: the test steps the simulator itself) and
its callbacks are called directly with messages whose contents hypothesis draws:
floats of any magnitude, arrays of any length, any joint names and frame ids, stamps
of any value (0, backwards, ahead of simulated time, out-of-range fields). Nothing
may escape a callback; a command rejected for its stamp is dropped (not applied,
not a lockstep answer); one rejected for its contents is not applied; the state the
node publishes stays finite.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from geometry_msgs.msg import WrenchStamped
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from sensor_msgs.msg import JointState

from splitter_model.kinematics import joint_positions_from_radii
from splitter_model.model import RobotModel
from splitter_msgs_py import conversions as conv
from splitter_msgs_py import names
from splitter_msgs_py.inspection import record_publications
from splitter_msgs_py.parameters import rejection_counts
from splitter_msgs_py.testing import (
    ANY_TEXT,
    ANY_VECTOR3,
    FLOAT_LIST,
    assert_finite,
    joint_state_msg,
    node_under_test,
    publishers_on,
    wrench_msg,
)
from splitter_sim.core.stepping import MAX_JUMP_FORCE_N, MAX_JUMP_TORQUE_NM
from splitter_sim.simulator_node import SimulatorNode

# An overflow inside a callback means an implausible number got past validation.
pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")

MODEL = RobotModel()
DT_NS = 5_000_000  # [ns] simulation step
NS_PER_S = 1_000_000_000
FRAME = st.one_of(st.sampled_from([names.WORLD_FRAME, names.BASE_FRAME, ""]), ANY_TEXT)
# now / k steps behind now / zero / k ns ahead of now / raw fields
STAMP = st.one_of(
    st.just(("now",)),
    st.tuples(st.just("behind"), st.integers(1, 4)),
    st.just(("zero",)),
    st.tuples(st.just("ahead"), st.sampled_from([1, DT_NS, NS_PER_S, 2**62])),
    st.tuples(st.just("raw"), st.integers(-(2**31), 2**31 - 1), st.integers(0, 2**32 - 1)),
)
RADII = st.tuples(
    st.floats(float(MODEL.radii_min_m[0]), float(MODEL.radii_max_m[0])),
    st.floats(float(MODEL.radii_min_m[1]), float(MODEL.radii_max_m[1])),
    st.floats(float(MODEL.radii_min_m[2]), float(MODEL.radii_max_m[2])),
)
# (names, positions, velocities, efforts): a valid command in any joint order, or anything
GOOD_JOINTS = st.tuples(
    st.permutations(range(names.N_JOINTS)),
    RADII,
    st.lists(st.floats(-1.0, 1.0), min_size=names.N_JOINTS, max_size=names.N_JOINTS),
).map(
    lambda x: (
        [names.JOINT_NAMES[i] for i in x[0]],
        [float(joint_positions_from_radii(MODEL, x[1])[i]) for i in x[0]],
        [x[2][i] for i in x[0]],
        [],
    )
)
ANY_JOINTS = st.tuples(
    st.one_of(
        st.permutations(names.JOINT_NAMES).map(list),
        st.lists(st.one_of(st.sampled_from(names.JOINT_NAMES), ANY_TEXT), max_size=27),
    ),
    FLOAT_LIST,
    FLOAT_LIST,
    FLOAT_LIST,
)
GOOD_JUMP = st.tuples(
    st.just(names.WORLD_FRAME),
    st.tuples(*[st.floats(-500.0, 500.0)] * 3),
    st.tuples(*[st.floats(-500.0, 500.0)] * 3),
)
STEP = st.one_of(
    st.tuples(st.just("joints"), STAMP, st.one_of(GOOD_JOINTS, ANY_JOINTS)),
    st.tuples(
        st.just("jump"), STAMP, st.one_of(GOOD_JUMP, st.tuples(FRAME, ANY_VECTOR3, ANY_VECTOR3))
    ),
    st.tuples(st.just("step"), st.integers(1, 3), st.none()),
)
SETTINGS = settings(
    max_examples=100,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)


def make_stamp(spec: tuple, now_ns: int) -> Time:
    kind = spec[0]
    if kind == "now":
        t = now_ns
    elif kind == "behind":
        t = max(0, now_ns - spec[1] * DT_NS)
    elif kind == "zero":
        t = 0
    elif kind == "ahead":
        t = now_ns + spec[1]
    else:
        return Time(sec=spec[1], nanosec=spec[2])
    return Time(sec=min(t // NS_PER_S, 2**31 - 1), nanosec=t % NS_PER_S)


def rejections(node) -> int:
    return sum(rejection_counts(node).values())


@pytest.fixture
def make_node(ros_context):
    """Builds a simulator that lives for one hypothesis example (``with make_node() as n``)."""
    return functools.partial(node_under_test, SimulatorNode, ros_context)


def _step(node: SimulatorNode, n: int) -> None:
    for _ in range(n):
        node.tick.step()
        node._publish_state()


def _stamp_ok(stamp: Time, now_ns: int, last_ns: int | None) -> bool:
    if stamp.sec < 0 or stamp.nanosec >= NS_PER_S:
        return False
    t = stamp.sec * NS_PER_S + stamp.nanosec
    return t <= now_ns and (last_ns is None or t >= last_ns)


@SETTINGS
@given(steps=st.lists(STEP, max_size=10))
def test_command_callbacks_survive_any_message(make_node, steps) -> None:
    with make_node() as node:
        published = record_publications(node)
        sim = node.tick.sim
        node._publish_state()
        last: dict[str, int | None] = {names.JOINT_COMMANDS: None, names.JUMP_COMMAND: None}
        for kind, spec, content in steps:
            if kind == "step":
                _step(node, spec)
                continue
            now = sim.time_ns
            stamp = make_stamp(spec, now)
            topic = names.JOINT_COMMANDS if kind == "joints" else names.JUMP_COMMAND
            stamp_ok = _stamp_ok(stamp, now, last[topic])
            arrived_before = node.tick.lockstep.stamps[topic]
            cmd_before = (sim._cmd_q, sim._cmd_qd, sim._jump_force)
            rejected_before = rejections(node)
            if kind == "joints":
                node._on_joint_commands(joint_state_msg(stamp, *content))
            else:
                node._on_jump_command(wrench_msg(stamp, *content))
            cmd_after = (sim._cmd_q, sim._cmd_qd, sim._jump_force)
            changed = any(a is not b for a, b in zip(cmd_after, cmd_before, strict=True))
            event(f"{kind}: {'applied' if changed else 'rejected'}")
            if not stamp_ok:  # dropped: not applied, not a lockstep answer
                assert not changed
                assert node.tick.lockstep.stamps[topic] == arrived_before
                assert rejections(node) == rejected_before + 1
                continue
            t = conv.stamp_from_msg(stamp)
            last[topic] = t
            assert node.tick.lockstep.stamps[topic] == t  # answers its tick, good or bad
            if not changed:
                assert rejections(node) == rejected_before + 1
            elif kind == "joints":
                joint_names, position, velocity, _ = content
                order = [list(joint_names).index(n) for n in names.JOINT_NAMES]
                np.testing.assert_array_equal(sim._cmd_q, np.array(position)[order])
                if velocity:
                    np.testing.assert_array_equal(sim._cmd_qd, np.array(velocity)[order])
                limits = sim.joint_limits
                assert np.all(sim._cmd_q >= limits.position_min)
                assert np.all(sim._cmd_q <= limits.position_max)
                assert np.all(np.abs(sim._cmd_qd) <= limits.speed_max)
            else:
                frame, force, torque = content
                assert frame == names.WORLD_FRAME
                assert np.linalg.norm(force) <= MAX_JUMP_FORCE_N
                assert np.linalg.norm(torque) <= MAX_JUMP_TORQUE_NM
                # (both hemis' pushes: their sum, to the rounding of the torque's part)
                scale = np.linalg.norm(force) + np.linalg.norm(torque)
                np.testing.assert_allclose(sim._jump_force, force, rtol=0.0, atol=1e-12 * scale)
        _step(node, 2)
        assert sim.state().is_finite()
        assert published[names.JOINT_STATES], "the state was published"
        for messages in published.values():
            for msg in messages:
                assert_finite(msg)


# --- stamps that used to be taken as they came ---------------------------------------------
@pytest.mark.parametrize(
    ("label", "stamp_of"),
    [
        ("zero", lambda now: Time()),
        ("backwards", lambda now: conv.stamp_to_msg(now - 2 * DT_NS)),
        ("ahead of simulated time", lambda now: conv.stamp_to_msg(now + DT_NS)),
        ("far ahead", lambda now: Time(sec=2_000_000_000)),
        ("nanosec out of range", lambda now: Time(sec=0, nanosec=4_000_000_000)),
        ("negative", lambda now: Time(sec=-1)),
    ],
)
def test_badly_stamped_commands_are_dropped(make_node, label: str, stamp_of) -> None:
    """After a good command at t = 20 ms, a command stamped 0, earlier, or ahead of the
    simulated time neither changes the commands in force nor answers a lockstep tick."""
    with make_node() as node:
        sim = node.tick.sim
        node._publish_state()
        _step(node, 4)
        now = sim.time_ns
        good = joint_positions_from_radii(MODEL, (2.7, 0.25, 0.18))
        node._on_joint_commands(conv.joint_state_to_msg(now, good))
        node._on_jump_command(conv.wrench_to_msg(now, (0.0, 0.0, 5.0)))
        q, force = sim._cmd_q, sim._jump_force
        assert node.tick.lockstep.stamps == dict.fromkeys(node.tick.lockstep.stamps, now)
        other = joint_positions_from_radii(MODEL, (2.0, 0.3, 0.3))
        bad_joint = conv.joint_state_to_msg(0, other)
        bad_joint.header.stamp = stamp_of(now)
        bad_jump = conv.wrench_to_msg(0, (0.0, 0.0, 50.0))
        bad_jump.header.stamp = stamp_of(now)
        node._on_joint_commands(bad_joint)
        node._on_jump_command(bad_jump)
        assert sim._cmd_q is q and sim._jump_force is force, label
        assert node.tick.lockstep.stamps == dict.fromkeys(node.tick.lockstep.stamps, now), label
        assert rejection_counts(node) == {"joint_commands": 1, "jump_command": 1}


def test_a_refused_command_answers_no_tick_while_a_stranger_publishes_on_its_topic(
    make_node, ros_context
) -> None:
    """Two publishers on each command topic (the graph's node and a stranger): a command
    refused for its contents may be the stranger's, so the tick waits for a good one."""
    commands = {names.JOINT_COMMANDS: JointState, names.JUMP_COMMAND: WrenchStamped}
    with make_node() as node, publishers_on(ros_context, node, commands):
        sim = node.tick.sim
        node._publish_state()
        _step(node, 2)
        now = sim.time_ns
        q, force = sim._cmd_q, sim._jump_force
        stamp = make_stamp(("now",), now)
        unknown = joint_state_msg(stamp, ["x"] * names.N_JOINTS, [0.0] * names.N_JOINTS)
        node._on_joint_commands(unknown)
        node._on_jump_command(wrench_msg(stamp, names.BASE_FRAME, (0, 0, 1), (0, 0, 0)))
        assert sim._cmd_q is q and sim._jump_force is force
        assert node.tick.lockstep.stamps == dict.fromkeys(node.tick.lockstep.stamps)
        assert rejection_counts(node) == {"joint_commands": 1, "jump_command": 1}
        good = joint_positions_from_radii(MODEL, (2.7, 0.25, 0.18))
        node._on_joint_commands(conv.joint_state_to_msg(now, good))
        node._on_jump_command(conv.wrench_to_msg(now, (0.0, 0.0, 5.0)))
        assert node.tick.lockstep.stamps == dict.fromkeys(node.tick.lockstep.stamps, now)


@pytest.mark.parametrize(
    ("force", "torque"),
    [((0.0, 0.0, 1e300), (0.0, 0.0, 0.0)), ((0.0, 0.0, 40.0), (1e300, 0.0, 0.0))],
)
def test_huge_jump_wrench_is_rejected_but_answers_its_tick(make_node, force, torque) -> None:
    with make_node() as node:
        node._publish_state()
        node._on_jump_command(wrench_msg(Time(), names.WORLD_FRAME, force, torque))
        assert node.tick.sim._jump_force == (0.0, 0.0, 0.0)
        assert node.tick.lockstep.stamps[names.JUMP_COMMAND] == 0
        assert rejection_counts(node) == {"jump_command": 1}


def test_shape_at_rest_without_joint_velocities() -> None:
    """ShapeKinematics.evaluate with qd None (and accelerations given) is the rest shape."""
    from splitter_sim.core.shape import ShapeKinematics

    kin = ShapeKinematics(MODEL)
    q = joint_positions_from_radii(MODEL, (2.0, 0.3, 0.2))
    rest = kin.evaluate(q)
    other = kin.evaluate(q, None, np.ones(names.N_JOINTS))
    assert other.inertia == rest.inertia
    assert other.h == (0.0, 0.0, 0.0)


def _joint_command(stamp_ns: int, radii: tuple[float, float, float], tether_v: float) -> JointState:
    """A valid joint command (names in order), the tether moving at ``tether_v``."""
    velocity = np.zeros(names.N_JOINTS)
    velocity[-1] = tether_v
    return conv.joint_state_to_msg(stamp_ns, joint_positions_from_radii(MODEL, radii), velocity)


def test_real_time_queues_a_point_stamped_ahead_and_applies_it_at_its_stamp(make_node) -> None:
    with make_node(mode="real_time", command_extrapolation_s=0.25) as node:
        _step(node, 2)  # t = 10 ms
        ahead = 30_000_000
        node._on_joint_commands(_joint_command(ahead, (2.7, 0.2, 0.2), -0.1))
        assert len(node.tick.queue) == 1
        assert node.tick.sim._cmd_t_ns == 0  # not in force yet
        while node.tick.sim.time_ns < ahead:
            node.tick.step()
            node._publish_state()
        node.tick.step()  # the step from the stamp applies it first
        assert node.tick.sim._cmd_t_ns == ahead and len(node.tick.queue) == 0
        assert node.tick.late_joint_commands == 0
        # a point earlier than the one in force, or too far ahead, is refused (counted)
        node._on_joint_commands(_joint_command(ahead - DT_NS, (2.7, 0.2, 0.2), 0.0))
        node._on_joint_commands(
            _joint_command(node.tick.sim.time_ns + 10 * NS_PER_S, (2.7, 0.2, 0.2), 0.0)
        )
        assert rejection_counts(node)["joint_commands"] == 2
        assert node.tick.sim._cmd_t_ns == ahead


def test_real_time_a_late_point_is_followed_from_its_stamp_and_counted(make_node) -> None:
    with make_node(mode="real_time", command_extrapolation_s=0.25) as node:
        _step(node, 4)  # t = 20 ms
        node._on_joint_commands(_joint_command(10_000_000, (2.7, 0.2, 0.2), -0.1))
        assert node.tick.late_joint_commands == 1
        assert node.tick.sim._cmd_t_ns == 10_000_000  # its stamp, not its arrival
        values = node.tick.latency.values()
        assert values["latency_joint_commands_last_ms"] == pytest.approx(10.0)


def test_lockstep_refuses_a_point_stamped_ahead(make_node) -> None:
    with make_node() as node:
        _step(node, 2)
        node._on_joint_commands(_joint_command(node.tick.sim.time_ns + DT_NS, (2.7, 0.2, 0.2), 0.0))
        assert rejection_counts(node)["joint_commands"] == 1
        assert len(node.tick.queue) == 0
