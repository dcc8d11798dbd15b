"""The simulator node spun in-process: stamps, lockstep, bad input, bad parameters."""

from __future__ import annotations

import math
import time
from collections import defaultdict

import numpy as np
import pytest
from geometry_msgs.msg import WrenchStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu, JointState

from splitter_model.actuators import TETHER_INDEX
from splitter_model.kinematics import joint_positions_from_radii
from splitter_model.model import RobotModel
from splitter_msgs_py import conversions as conv
from splitter_msgs_py import names
from splitter_msgs_py.parameters import InvalidParameterError
from splitter_msgs_py.qos import qos_for
from splitter_msgs_py.testing import spin_until
from splitter_sim.core.stepping import pushing_hemi
from splitter_sim.messages import masses_from_msg
from splitter_sim.simulator_node import SimulatorNode

DT_NS = 5_000_000
TIMEOUT_S = 20.0  # [s] of wall time for a short run (a loaded machine is slow)
EVERY_STEP = (  # published at every step
    names.CLOCK,
    names.IMU,
    names.ODOM,
    names.INERTIA,
    names.JOINT_STATES,
    *names.CONTACT_WRENCHES,
)
PUBLISHED = (*EVERY_STEP, names.MARKERS, names.SCENE_MASSES, names.DIAGNOSTICS)


class Probe(Node):
    """Keeps every message of the simulator's topics."""

    def __init__(self, commands: bool = False, **kwargs) -> None:
        super().__init__("probe", **kwargs)
        self.messages: dict[str, list] = defaultdict(list)
        for topic in PUBLISHED:
            self.create_subscription(
                conv.TOPIC_MESSAGE_CLASSES[topic],
                topic,
                lambda msg, topic=topic: self.messages[topic].append(msg),
                qos_for(topic),
            )
        if commands:  # (a lockstep simulator waits for every command topic with a publisher)
            self.joint_pub = self.create_publisher(
                JointState, names.JOINT_COMMANDS, qos_for(names.JOINT_COMMANDS)
            )
            self.jump_pub = self.create_publisher(
                WrenchStamped, names.JUMP_COMMAND, qos_for(names.JUMP_COMMAND)
            )

    def stamps(self, topic: str) -> list[int]:
        if topic == names.CLOCK:
            return [conv.stamp_from_msg(m.clock) for m in self.messages[topic]]
        if topic == names.MARKERS:
            return [conv.stamp_from_msg(m.markers[0].header.stamp) for m in self.messages[topic]]
        return [conv.stamp_from_msg(m.header.stamp) for m in self.messages[topic]]

    def diagnostics(self) -> list[dict]:
        return [conv.diagnostics_from_msg(m)[0].values for m in self.messages[names.DIAGNOSTICS]]


def _simulator(context, **parameters) -> SimulatorNode:
    # startup_wait_s: in-process discovery is immediate; topics nobody serves cost the full wait
    defaults = {"startup_wait_s": 0.5, "duration_s": 0.1, "lockstep_timeout_s": 0.3}
    defaults.update(parameters)
    overrides = [Parameter(k, value=v) for k, v in defaults.items()]
    return SimulatorNode(context=context, parameter_overrides=overrides)


def _drain(executor: SingleThreadedExecutor, probe: Probe, quiet_s: float = 0.3) -> None:
    """Spin until the probe has received nothing new for ``quiet_s`` (a loaded machine is slow)."""
    deadline = time.monotonic() + 20.0
    count, last_change = -1, time.monotonic()
    while time.monotonic() - last_change < quiet_s:
        assert time.monotonic() < deadline, "messages kept coming"
        executor.spin_once(timeout_sec=0.01)
        now_count = sum(len(v) for v in probe.messages.values())
        if now_count != count:
            count, last_change = now_count, time.monotonic()


@pytest.fixture
def graph(ros_context):
    nodes: list[Node] = []
    executor = SingleThreadedExecutor(context=ros_context)

    def add(node: Node) -> Node:
        nodes.append(node)
        executor.add_node(node)
        return node

    yield ros_context, executor, add
    for node in nodes:
        executor.remove_node(node)
        node.destroy_node()
    executor.shutdown()


def test_publishes_every_topic_stamped_on_its_grid(graph) -> None:
    context, executor, add = graph
    probe = add(Probe(context=context))
    sim = add(_simulator(context))
    spin_until(executor, sim.finished.done, TIMEOUT_S)
    _drain(executor, probe)  # deliver the last messages
    steps = list(range(0, 100_000_001, DT_NS))
    for topic in EVERY_STEP:
        assert probe.stamps(topic) == steps, topic
    assert probe.stamps(names.MARKERS) == [0, 40_000_000, 80_000_000]
    assert probe.stamps(names.SCENE_MASSES) == [0, 40_000_000, 80_000_000]
    # the markers are drawn from the scene the node publishes: the same masses
    for scene_msg, marker_msg in zip(
        probe.messages[names.SCENE_MASSES], probe.messages[names.MARKERS], strict=True
    ):
        spheres = [m.pose.position for m in marker_msg.markers[:10]]
        np.testing.assert_array_equal(
            masses_from_msg(scene_msg), [[p.x, p.y, p.z] for p in spheres]
        )
    # 10 Hz plus the final status at the end of duration_s
    assert probe.stamps(names.DIAGNOSTICS) == [0, 100_000_000, 100_000_000]
    final = probe.diagnostics()[-1]
    assert final["finished"] is True
    markers = probe.messages[names.MARKERS][0].markers
    assert [m.ns for m in markers[:12]] == ["splitter_masses"] * 10 + [
        "splitter_tether",
        "splitter_limbs",
    ]
    # no ground contact in flight: the body axes and the angular momentum, no contact force
    arrows = {m.text: m for m in markers[12:] if m.ns == "splitter_arrows"}
    assert set(arrows) == {"axis_x", "axis_y", "axis_z", "angular_momentum"}
    # Contents: the paper's initial state, finite, with H conserved between samples.
    imu = [conv.imu_from_msg(m) for m in probe.messages[names.IMU]]
    np.testing.assert_allclose(imu[0].angular_velocity_rad_s, [-0.3, -0.9, 0.9])
    inertia = conv.vector3_from_msg(probe.messages[names.INERTIA][0]).vector
    np.testing.assert_allclose(inertia, [0.48, 141.36, 141.36])
    h = [d["angular_momentum_norm_kg_m2_s"] for d in probe.diagnostics()]
    assert h[-1] == pytest.approx(h[0], rel=1e-9)
    joints = conv.joint_state_from_msg(probe.messages[names.JOINT_STATES][-1])
    assert joints.position[names.JOINT_INDEX[names.TETHER_JOINT]] == pytest.approx(5.6)
    wrench = conv.wrench_from_msg(probe.messages[names.CONTACT_WRENCH_A][0])
    assert wrench.frame_id == names.WORLD_FRAME and not wrench.force_n.any()


class Controller(Node):
    """Answers each control tick's IMU with a joint command stamped with the tick."""

    def __init__(self, skip_tick_ns: int | None = None, **kwargs) -> None:
        super().__init__("controller", **kwargs)
        self.pub = self.create_publisher(
            JointState, names.JOINT_COMMANDS, qos_for(names.JOINT_COMMANDS)
        )
        self.create_subscription(Imu, names.IMU, self._on_imu, qos_for(names.IMU))
        self.skip_tick_ns = skip_tick_ns
        self.target = joint_positions_from_radii(RobotModel(), (2.7, 0.25, 0.18))
        self.answered: list[int] = []

    def _on_imu(self, msg: Imu) -> None:
        t = conv.stamp_from_msg(msg.header.stamp)
        if t % 10_000_000 or t == self.skip_tick_ns:
            return
        self.answered.append(t)
        self.pub.publish(conv.joint_state_to_msg(t, self.target))


def test_lockstep_waits_for_the_tick_command_and_times_out_with_a_reason(graph) -> None:
    context, executor, add = graph
    probe = add(Probe(context=context))
    controller = add(Controller(skip_tick_ns=50_000_000, context=context))
    sim = add(_simulator(context, duration_s=0.1, lockstep_timeout_s=0.4))
    start = time.monotonic()
    spin_until(executor, sim.finished.done, TIMEOUT_S)
    wall = time.monotonic() - start
    _drain(executor, probe)
    # Every tick but the skipped one answered; the skipped one cost one timeout.
    assert controller.answered == [t for t in range(0, 100_000_001, 10_000_000) if t != 50_000_000]
    assert wall >= 0.4
    assert probe.diagnostics()[-1]["lockstep_timeouts"] == 1
    # The commands were applied: the joints moved toward the target.
    last = conv.joint_state_from_msg(probe.messages[names.JOINT_STATES][-1])
    assert last.position[TETHER_INDEX] < 5.6 - 0.01


def test_bad_commands_are_rejected_and_the_node_keeps_publishing_finite_data(graph) -> None:
    context, executor, add = graph
    probe = add(Probe(commands=True, context=context))
    # real time at half speed: 0.6 s of wall time for the commands to arrive, even when loaded
    sim = add(_simulator(context, duration_s=0.3, mode="real_time", rate_factor=0.5))
    spin_until(executor, lambda: len(probe.messages[names.CLOCK]) > 2, TIMEOUT_S)
    good = joint_positions_from_radii(RobotModel(), (2.7, 0.25, 0.18))
    bad_names = conv.joint_state_to_msg(0, good)
    bad_names.name[0] = "hemi_c_y_pos_hip_abduction"
    too_far = good.copy()
    too_far[TETHER_INDEX] = 7.5  # [m] beyond the 6 m of tether
    probe.joint_pub.publish(conv.joint_state_to_msg(0, good))
    nan_msg = conv.joint_state_to_msg(0, good)
    nan_msg.position[3] = math.nan  # conversions refuse NaN, so forge it in the message
    probe.joint_pub.publish(nan_msg)
    probe.joint_pub.publish(bad_names)
    probe.joint_pub.publish(conv.joint_state_to_msg(0, too_far))
    jump = conv.wrench_to_msg(0, (0.0, 0.0, 10.0))
    jump.wrench.force.z = math.inf
    probe.jump_pub.publish(jump)
    spin_until(executor, sim.finished.done, TIMEOUT_S)
    _drain(executor, probe)
    final = probe.diagnostics()[-1]
    assert final["rejected_joint_commands"] == 3
    assert final["rejected_jump_commands"] == 1
    # The good command stayed in force: the tether reels toward 5.4 m, never toward 7.5 m.
    for msg in probe.messages[names.JOINT_STATES]:
        sample = conv.joint_state_from_msg(msg)  # raises on NaN
        assert 5.4 - 1e-9 <= sample.position[TETHER_INDEX] <= 5.6 + 1e-9
    assert (
        conv.joint_state_from_msg(probe.messages[names.JOINT_STATES][-1]).position[TETHER_INDEX]
        < 5.59
    )
    for msg in probe.messages[names.IMU]:
        conv.imu_from_msg(msg)
    for msg in probe.messages[names.ODOM]:
        conv.odom_from_msg(msg)
    assert len(probe.messages[names.CLOCK]) == 61


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("contact_stiffness_n_m", -1.0),
        ("initial_radii_m", [2.8, 0.9, 0.2]),
        ("gravity", "jupiter"),
        ("mode", "fast"),
        ("markers_period_s", 0.0333),
        ("initial_position_m", [0.0, math.nan, 1.0]),
        ("ground_slope_deg", 90.0),
        ("ground_slope_deg", math.nan),
        ("ground_steps_m", [5.0, 6.0, -1.0, 1.0]),  # 4 values: not a step
        ("ground_steps_m", [6.0, 5.0, -1.0, 1.0, 0.1]),  # x_max before x_min
        ("leg_hold_stiffness_n_m", -1.0),
    ],
)
def test_an_invalid_parameter_stops_start_up_naming_it(ros_context, name, value) -> None:
    with pytest.raises(InvalidParameterError, match=name):
        SimulatorNode(context=ros_context, parameter_overrides=[Parameter(name, value=value)])


def test_jump_command_torque_selects_the_pushing_hemi(graph) -> None:
    context, executor, add = graph
    sim = add(_simulator(context, duration_s=0.01, gravity="moon"))
    spin_until(executor, sim.finished.done, TIMEOUT_S)
    state = sim.tick.last_published
    assert state is not None
    force = np.array([40.0, 0.0, 40.0])
    lever_b = state.mass_positions_world_m[5] - state.position_m
    lever_a = state.mass_positions_world_m[0] - state.position_m
    assert pushing_hemi(sim.tick.last_published, force, np.cross(lever_b, force)) == "b"
    assert pushing_hemi(sim.tick.last_published, force, np.cross(lever_a, force)) == "a"
    assert pushing_hemi(sim.tick.last_published, force, np.zeros(3)) == "auto"
