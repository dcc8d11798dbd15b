"""The ik_tether_allocator node spun in-process: stamps, bad input, fallback, parameters."""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu, JointState

from splitter_ik.core.joint_health import JointHealthConfig
from splitter_ik.ik_tether_allocator_node import IkTetherAllocatorNode
from splitter_model.actuators import TETHER_INDEX
from splitter_model.kinematics import radii_from_joint_positions
from splitter_model.model import PAPER_INITIAL_RADII_M, RobotModel, principal_inertia
from splitter_msgs_py import conversions as conv
from splitter_msgs_py import names
from splitter_msgs_py.parameters import InvalidParameterError, rejection_counts
from splitter_msgs_py.qos import qos_for

MODEL = RobotModel()
TICK_NS = 10_000_000


class Probe(Node):
    """Plays the MPC (setpoints) and the simulator (imu, inertia); keeps commands."""

    def __init__(self, setpoints: bool = True, **kwargs) -> None:
        super().__init__("probe", **kwargs)
        self.commands: list[JointState] = []
        self.diagnostics: list[DiagnosticArray] = []
        self.create_subscription(
            JointState, names.JOINT_COMMANDS, self.commands.append, qos_for(names.JOINT_COMMANDS)
        )
        self.create_subscription(
            DiagnosticArray, names.DIAGNOSTICS, self.diagnostics.append, qos_for(names.DIAGNOSTICS)
        )
        self.setpoint_pub = None
        if setpoints:
            self.setpoint_pub = self.create_publisher(
                Vector3Stamped, names.INERTIA_SETPOINT, qos_for(names.INERTIA_SETPOINT)
            )
        self.imu_pub = self.create_publisher(Imu, names.IMU, qos_for(names.IMU))
        self.inertia_pub = self.create_publisher(
            Vector3Stamped, names.INERTIA, qos_for(names.INERTIA)
        )

    def setpoint(self, t_ns: int, inertia: list[float] | np.ndarray) -> None:
        msg = Vector3Stamped()
        msg.header.stamp = conv.stamp_to_msg(t_ns)
        msg.header.frame_id = names.BASE_FRAME
        msg.vector.x, msg.vector.y, msg.vector.z = (float(v) for v in inertia)  # NaN allowed
        self.setpoint_pub.publish(msg)

    def imu(self, t_ns: int, w: list[float]) -> None:
        self.imu_pub.publish(conv.imu_to_msg(t_ns, [1.0, 0.0, 0.0, 0.0], w, [0.0, 0.0, 0.0]))

    def stamps(self) -> list[int]:
        return [conv.stamp_from_msg(m.header.stamp) for m in self.commands]


def _spin(executor: SingleThreadedExecutor, until: Callable[[], bool], timeout_s: float = 10.0):
    deadline = time.monotonic() + timeout_s
    while not until():
        assert time.monotonic() < deadline, "timed out waiting"
        executor.spin_once(timeout_sec=0.01)


def _graph(ros_context, setpoints: bool = True, **parameters):
    overrides = [Parameter(k, value=v) for k, v in parameters.items()]
    node = IkTetherAllocatorNode(context=ros_context, parameter_overrides=overrides)
    probe = Probe(setpoints=setpoints, context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    executor.add_node(probe)
    pubs = [probe.imu_pub, probe.inertia_pub] + ([probe.setpoint_pub] if setpoints else [])
    _spin(executor, lambda: all(p.get_subscription_count() > 0 for p in pubs))
    _spin(executor, lambda: node.count_publishers(names.IMU) > 0)
    return node, probe, executor


def _teardown(node: Node, probe: Node, executor: SingleThreadedExecutor) -> None:
    executor.shutdown()
    probe.destroy_node()
    node.destroy_node()


def test_setpoints_answered_with_their_stamp_bad_ones_rejected(ros_context) -> None:
    node, probe, executor = _graph(ros_context, initialize_from_measured_inertia=False)
    try:
        assert node.get_parameter("use_sim_time").value is True
        target = principal_inertia(MODEL, [2.0, 0.3, 0.15])
        bad = {5: [math.nan, 1.0, 1.0], 6: [-1.0, 140.0, 140.0], 7: [1.0, math.inf, 2.0]}
        n = 30
        for k in range(n):
            t = k * TICK_NS
            probe.imu(t, [0.0, 1.0, 0.0])
            probe.setpoint(t, bad.get(k, target))
            _spin(executor, lambda k=k: len(probe.commands) == k + 1)
        assert probe.stamps() == [k * TICK_NS for k in range(n)]
        samples = [conv.joint_state_from_msg(m) for m in probe.commands]
        for s in samples:
            assert s.velocity is not None
            assert np.all(np.isfinite(s.position)) and np.all(np.isfinite(s.velocity))
        # the commands start from the initial radii and head for the target
        radii = [radii_from_joint_positions(MODEL, s.position) for s in samples]
        assert radii[0][0] == pytest.approx(PAPER_INITIAL_RADII_M[0])  # planned at t = 0
        assert radii[1][0] < PAPER_INITIAL_RADII_M[0]
        assert radii[-1][1] == pytest.approx(0.3, abs=1e-9)  # the limbs got there
        assert np.all(np.diff([r[0] for r in radii]) <= 1e-12)  # the tether only reels in
        # a rejected tick holds the last good setpoint: the tether keeps going the same way
        for k in bad:
            dq = samples[k + 1].position - samples[k].position
            np.testing.assert_allclose(samples[k].velocity, dq / 0.01, atol=1e-9)
            assert samples[k].velocity[TETHER_INDEX] < 0.0
        # diagnostics at 0, 0.1, 0.2 s of simulated time
        _spin(executor, lambda: len(probe.diagnostics) == 3)
        diag_stamps = [conv.stamp_from_msg(m.header.stamp) for m in probe.diagnostics]
        assert diag_stamps == [0, 100_000_000, 200_000_000]
        statuses = [conv.diagnostics_from_msg(m)[0] for m in probe.diagnostics]
        second = statuses[1]  # ticks 1..10: the three bad setpoints are in it
        assert second.name == "ik_tether_allocator: allocation"
        assert second.values["setpoints_rejected"] == 3.0
        assert second.level == 1
        assert second.values["ticks_rate_limited"] == 10.0
        assert second.values["min_tension_margin_n"] >= 0.0
        assert statuses[2].values["setpoints_rejected"] == 0.0
    finally:
        _teardown(node, probe, executor)


def test_unreachable_setpoint_projected_and_reported(ros_context) -> None:
    node, probe, executor = _graph(ros_context)
    try:
        for k in range(11):
            probe.imu(k * TICK_NS, [0.0, 1.0, 0.0])
            probe.setpoint(k * TICK_NS, [0.1, 300.0, 100.0])
            _spin(executor, lambda k=k: len(probe.commands) == k + 1)
        assert node.core.last_allocation is not None and node.core.last_allocation.saturated
        _spin(executor, lambda: len(probe.diagnostics) == 2)  # stamped 0 and 0.1 s
        status = conv.diagnostics_from_msg(probe.diagnostics[-1])[0]
        assert status.values["setpoints_projected"] == 10.0
        assert status.values["max_saturation_kg_m2"] > 1.0
        assert "projected" in status.message
    finally:
        _teardown(node, probe, executor)


def test_answers_inertia_ticks_without_a_setpoint_publisher(ros_context) -> None:
    node, probe, executor = _graph(ros_context, setpoints=False)
    try:
        assert node.count_publishers(names.INERTIA_SETPOINT) == 0
        measured = principal_inertia(MODEL, [2.5, 0.25, 0.25])
        for k in range(6):  # 200 Hz state: every other step is a control tick
            t = k * TICK_NS // 2
            probe.inertia_pub.publish(conv.vector3_to_msg(t, measured))
            probe.imu(t, [0.0, 0.8, 0.0])
            if k % 2 == 0:
                _spin(executor, lambda k=k: len(probe.commands) == k // 2 + 1)
        for _ in range(20):  # off-grid steps are not answered
            executor.spin_once(timeout_sec=0.01)
        assert probe.stamps() == [0, TICK_NS, 2 * TICK_NS]
        # it started from the measured state and holds it
        for m in probe.commands:
            s = conv.joint_state_from_msg(m)
            np.testing.assert_allclose(
                radii_from_joint_positions(MODEL, s.position), [2.5, 0.25, 0.25]
            )
            np.testing.assert_allclose(s.velocity, 0.0, atol=1e-12)
    finally:
        _teardown(node, probe, executor)


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("tension_margin_n", -1.0),
        ("control_period_s", 0.0),
        ("initial_radii_m", [5.0, 0.2, 0.2]),
        ("initial_radii_m", [2.8, 0.2]),
        ("speed_fraction", 2.0),
        ("stuck_window_s", 0.0),
        ("envelope_margin_m", math.nan),
        ("still_rad", 0.01),  # not below stuck_error_rad: a stuck joint could not show
    ],
)
def test_invalid_parameter_stops_start_up_naming_it(ros_context, name: str, value) -> None:
    with pytest.raises(InvalidParameterError, match=name):
        IkTetherAllocatorNode(
            context=ros_context, parameter_overrides=[Parameter(name, value=value)]
        )


def test_the_fault_detector_takes_its_thresholds_from_the_parameters(ros_context) -> None:
    node = IkTetherAllocatorNode(
        context=ros_context,
        parameter_overrides=[
            Parameter("envelope_margin_rad", value=0.05),
            Parameter("stuck_window_s", value=0.1),
        ],
    )
    try:
        config = node.core.health.config
        assert (config.envelope_margin_rad, config.stuck_window_s) == (0.05, 0.1)
        assert config.envelope_margin_m == JointHealthConfig().envelope_margin_m
    finally:
        node.destroy_node()


def test_a_stuck_knee_in_the_joint_states_is_found_and_published(ros_context) -> None:
    """The probe plays a robot whose hemi_a_y_pos_knee stays where it started while every
    other joint follows the commands; a NaN joint state and one stamped behind in between
    are refused. The allocator finds the knee stuck once it is asked to move and
    publishes /splitter/joint_health with the knee and the radius bounds that remain."""
    node, probe, executor = _graph(  # the probe's joints: the last command, one tick late
        ros_context,
        initialize_from_measured_inertia=False,
        servo_latency_s=TICK_NS * 1e-9,
        command_extrapolation_s=0.0,
    )
    health: list[DiagnosticArray] = []
    probe.create_subscription(
        DiagnosticArray, names.JOINT_HEALTH, health.append, qos_for(names.JOINT_HEALTH)
    )
    joints_pub = probe.create_publisher(JointState, names.JOINT_STATES, qos_for(names.JOINT_STATES))
    _spin(executor, lambda: joints_pub.get_subscription_count() > 0)
    knee = names.JOINT_INDEX["hemi_a_y_pos_knee"]
    try:
        target = principal_inertia(MODEL, [2.8, 0.35, 0.2])  # the y knees must move
        start = None
        for k in range(40):
            t = k * TICK_NS
            q = conv.joint_state_from_msg(probe.commands[-1]).position if probe.commands else None
            if q is not None:
                start = q[knee] if start is None else start
                q = q.copy()
                q[knee] = start
                joints_pub.publish(conv.joint_state_to_msg(t, q, np.zeros(25)))
                if k == 5:
                    bad = conv.joint_state_to_msg(t + 1, q, np.zeros(25))
                    bad.position[3] = math.nan
                    joints_pub.publish(bad)
                    joints_pub.publish(conv.joint_state_to_msg(t - TICK_NS, q, np.zeros(25)))
            probe.imu(t, [0.0, 1.0, 0.0])
            probe.setpoint(t, target)
            _spin(executor, lambda k=k: len(probe.commands) == k + 1)
        _spin(executor, lambda: len(health) > 0)
        found = conv.joint_health_from_msg(health[-1])
        assert found.symptoms == {"hemi_a_y_pos_knee": "stuck"}
        assert found.radius_min_m[1] > MODEL.limb_radius_min_m  # two y limbs held out
        first = conv.stamp_from_msg(health[0].header.stamp)
        assert first <= 30 * TICK_NS
        status = node.diagnostics_status()
        assert status.level == 2 and "hemi_a_y_pos_knee stuck" in status.values["faulty_joints"]
        assert rejection_counts(node).get("joint_states", 0) == 2  # the NaN, the one behind
    finally:
        _teardown(node, probe, executor)
