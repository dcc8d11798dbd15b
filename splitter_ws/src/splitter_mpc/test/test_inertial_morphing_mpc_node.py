"""inertial_morphing_mpc node in-process: lockstep answers, diagnostics, bad input, parameters."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import rclpy
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, TwistStamped, Vector3Stamped, WrenchStamped
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu
from std_msgs.msg import String

from splitter_model.model import PAPER_INITIAL_RADII_M, RobotModel, principal_inertia
from splitter_mpc.inertial_morphing_mpc_node import InertialMorphingMpcNode
from splitter_msgs_py import names
from splitter_msgs_py.conversions import (
    diagnostics_from_msg,
    diagnostics_to_msg,
    imu_to_msg,
    joint_health_status,
    pose_to_msg,
    stamp_from_msg,
    twist_to_msg,
    vector3_from_msg,
    vector3_to_msg,
    wrench_to_msg,
)
from splitter_msgs_py.parameters import InvalidParameterError, rejection_counts
from splitter_msgs_py.qos import LATCHED_QOS, qos_for
from splitter_msgs_py.testing import spin_for, spin_until, spun_together

MS = 1_000_000  # [ns]
I0 = principal_inertia(RobotModel(), PAPER_INITIAL_RADII_M)
W0 = np.array([-0.3, -0.9, 0.9])  # [rad/s]
Q0 = np.array([1.0, 0.0, 0.0, 0.0])
CONFIG_FILE = Path(__file__).resolve().parents[1] / "config" / "inertial_morphing_mpc.yaml"
FAST = [  # SX VM: no compiler or cache in tests; no wall-time deadline under CI load
    Parameter("compile", value=False),
    Parameter("max_solve_time_s", value=10.0),
]


class FakeGraph:
    """Publishes what the simulator and the gait manager would; records the MPC's output."""

    def __init__(self, context) -> None:
        self.node = rclpy.create_node("fake_graph", context=context)
        self.imu = self.node.create_publisher(Imu, names.IMU, qos_for(names.IMU))
        self.inertia = self.node.create_publisher(
            Vector3Stamped, names.INERTIA, qos_for(names.INERTIA)
        )
        self.w_ref = self.node.create_publisher(TwistStamped, names.ATTITUDE_REFERENCE, LATCHED_QOS)
        self.q_ref = self.node.create_publisher(
            PoseStamped, names.ATTITUDE_REFERENCE_POSE, LATCHED_QOS
        )
        self.phase = self.node.create_publisher(String, names.GAIT_PHASE, LATCHED_QOS)
        self.setpoints: list[Vector3Stamped] = []
        self.diagnostics: list[DiagnosticArray] = []
        self.node.create_subscription(
            Vector3Stamped,
            names.INERTIA_SETPOINT,
            self.setpoints.append,
            qos_for(names.INERTIA_SETPOINT),
        )
        self.node.create_subscription(
            DiagnosticArray, names.DIAGNOSTICS, self.diagnostics.append, qos_for(names.DIAGNOSTICS)
        )

    def publish_reference(self, t_ns: int = 0) -> None:
        self.w_ref.publish(twist_to_msg(t_ns, [0.0, 1.0, 0.0]))
        self.q_ref.publish(pose_to_msg(t_ns, Q0))

    def publish_state(self, t_ns: int, w=W0, inertia=I0) -> None:
        self.inertia.publish(vector3_to_msg(t_ns, inertia))
        self.imu.publish(imu_to_msg(t_ns, Q0, w, (0.0, 0.0, 0.0)))

    def stamps(self) -> list[int]:
        return [stamp_from_msg(m.header.stamp) // MS for m in self.setpoints]


@pytest.fixture
def graph(ros_context):
    mpc = InertialMorphingMpcNode(context=ros_context, parameter_overrides=FAST)
    fake = FakeGraph(ros_context)
    with spun_together(ros_context, mpc, fake.node) as executor:
        yield mpc, fake, executor


def tick(fake: FakeGraph, executor, t_ms: int, **state) -> None:
    fake.publish_state(t_ms * MS, **state)
    spin_until(executor, lambda: t_ms in fake.stamps())


def test_waits_for_the_reference_then_answers_every_tick(graph) -> None:
    mpc, fake, executor = graph
    fake.publish_state(0)
    spin_for(executor, 0.3)
    assert fake.setpoints == []  # first tick waits for the attitude reference
    fake.phase.publish(String(data="IN_FLIGHT"))
    fake.publish_reference(0)
    spin_until(executor, lambda: 0 in fake.stamps())
    for t_ms in range(10, 210, 10):
        tick(fake, executor, t_ms)
    assert fake.stamps() == list(range(0, 210, 10))  # one setpoint per tick, stamped t
    setpoints = np.array([vector3_from_msg(m).vector for m in fake.setpoints])
    assert np.all(np.isfinite(setpoints)) and np.max(np.abs(setpoints - I0)) > 0.01
    spin_until(executor, lambda: len(fake.diagnostics) >= 3)
    assert [stamp_from_msg(d.header.stamp) // MS for d in fake.diagnostics] == [0, 100, 200]
    status = diagnostics_from_msg(fake.diagnostics[-1])[0]
    assert status.name == "inertial_morphing_mpc: inertia setpoint"
    assert status.values["solves"] == 3.0 and status.values["failures"] == 0.0
    assert status.values["solve_ok"] is True and status.values["solver"] == "fatrop"
    assert status.values["solve_time_ms"] > 0.0 and status.values["iterations"] >= 1.0
    assert math.isfinite(status.values["cost"])
    assert mpc.controller.status.phase == "IN_FLIGHT"


def test_bad_messages_are_rejected_and_the_node_keeps_answering(graph) -> None:
    mpc, fake, executor = graph
    fake.publish_reference(0)
    fake.phase.publish(String(data="IN_FLIGHT"))
    tick(fake, executor, 0)
    bad_imu = imu_to_msg(10 * MS, Q0, W0, (0.0, 0.0, 0.0))
    bad_imu.angular_velocity.x = math.nan  # rejected imu
    fake.imu.publish(bad_imu)
    fake.inertia.publish(vector3_to_msg(10 * MS, [-1.0, 1.0, 1.0]))  # rejected inertia
    fake.phase.publish(String(data="FLYING"))  # unknown phase
    bad_pose = pose_to_msg(0, Q0)
    bad_pose.pose.orientation.w = 0.0  # not a unit quaternion
    fake.q_ref.publish(bad_pose)
    spin_for(executor, 0.2)
    # the tick with a good imu and a good inertia is answered from them
    tick(fake, executor, 10)
    tick(fake, executor, 20)
    assert fake.stamps() == [0, 10, 20]
    assert sum(rejection_counts(mpc).values()) == 4
    assert np.all(np.isfinite([vector3_from_msg(m).vector for m in fake.setpoints]))


def test_the_first_tick_waits_for_the_gait_phase(graph) -> None:
    """Reference before phase (message order): LAUNCH still holds the nominal shape."""
    mpc, fake, executor = graph
    fake.publish_reference(0)
    fake.imu.publish(imu_to_msg(0, Q0, W0, (0.0, 0.0, 0.0)))
    fake.inertia.publish(vector3_to_msg(0, 1.01 * I0))
    spin_for(executor, 0.3)
    assert fake.stamps() == []  # a phase publisher exists: no answer without its phase
    fake.phase.publish(String(data="LAUNCH"))
    spin_for(executor, 0.3)
    assert fake.stamps() == [0] and mpc.controller.status.phase == "LAUNCH"
    np.testing.assert_allclose(vector3_from_msg(fake.setpoints[0]).vector, 1.01 * I0)


def test_a_tick_waits_for_the_gait_managers_answer_and_plans_with_its_phase(graph) -> None:
    """With a gait manager in the graph, tick t is answered after its jump command stamped
    t, with the phase it published before: a LANDED at t = 10 ms counts at t = 10 ms
    (LANDED holds the last setpoint, where IN_FLIGHT plays the plan on)."""
    mpc, fake, executor = graph
    jump = fake.node.create_publisher(
        WrenchStamped, names.JUMP_COMMAND, qos_for(names.JUMP_COMMAND)
    )
    fake.publish_reference(0)
    fake.phase.publish(String(data="IN_FLIGHT"))
    fake.publish_state(0)
    spin_for(executor, 0.3)
    assert fake.stamps() == []  # the gait manager has not answered t = 0
    jump.publish(wrench_to_msg(0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), names.WORLD_FRAME))
    spin_until(executor, lambda: fake.stamps() == [0])
    fake.publish_state(10 * MS, inertia=1.05 * I0)
    spin_for(executor, 0.3)
    assert fake.stamps() == [0]
    fake.phase.publish(String(data="LANDED"))  # the gait's tick 10 ms: phase, then answer
    jump.publish(wrench_to_msg(10 * MS, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), names.WORLD_FRAME))
    spin_until(executor, lambda: fake.stamps() == [0, 10])
    assert mpc.controller.status.phase == "LANDED"
    # LANDED holds the last setpoint; IN_FLIGHT would have played the plan on
    held, first = (vector3_from_msg(m).vector for m in (fake.setpoints[1], fake.setpoints[0]))
    np.testing.assert_array_equal(held, first)


def test_landed_holds_the_nominal_inertia(graph) -> None:
    _mpc, fake, executor = graph
    fake.publish_reference(0)
    fake.phase.publish(String(data="LANDED"))
    spin_for(executor, 0.2)
    tick(fake, executor, 0)
    tick(fake, executor, 10, inertia=1.05 * I0)
    for message in fake.setpoints:
        np.testing.assert_allclose(vector3_from_msg(message).vector, I0)


def test_invalid_parameters_stop_the_node_naming_them(ros_context) -> None:
    for name, value in (("solver", "simplex"), ("horizon", 1), ("q_w", [1.0, 2.0])):
        with pytest.raises(InvalidParameterError, match=name):
            InertialMorphingMpcNode(
                context=ros_context, parameter_overrides=[*FAST, Parameter(name, value=value)]
            )
    with pytest.raises(InvalidParameterError, match="replan_period_s"):
        InertialMorphingMpcNode(
            context=ros_context,
            parameter_overrides=[*FAST, Parameter("replan_period_s", value=0.015)],
        )


def test_parameter_file_is_valid(ros_context) -> None:
    values = yaml.safe_load(CONFIG_FILE.read_text())["inertial_morphing_mpc"]["ros__parameters"]
    overrides = [Parameter(k, value=v) for k, v in values.items() if k != "compile"]
    node = InertialMorphingMpcNode(context=ros_context, parameter_overrides=[*overrides, *FAST])
    try:
        assert node.controller.config.mpc.horizon == 50
        assert node.controller.config.weights.q_t == (100.0, 10.0, 100.0)
    finally:
        node.destroy_node()


def test_joint_health_bounds_the_plans_from_the_next_tick_bad_ones_refused(graph) -> None:
    """/splitter/joint_health (the allocator's, after a fault): its radius bounds are planned
    within from the first tick after its stamp; one that names no known joint or has
    bounds out of order is refused, the last good kept."""
    mpc, fake, executor = graph
    pub = fake.node.create_publisher(
        DiagnosticArray, names.JOINT_HEALTH, qos_for(names.JOINT_HEALTH)
    )
    spin_until(executor, lambda: pub.get_subscription_count() > 0)
    fake.publish_reference(0)
    fake.phase.publish(String(data="IN_FLIGHT"))
    tick(fake, executor, 0)
    low, high = np.array([1.39, 0.2, 0.107]), np.array([1.41, 0.3, 0.397])  # reel locked
    bounds = SimpleNamespace(radius_min_m=low, radius_max_m=high)
    status = joint_health_status({names.JOINT_INDEX["tether"]: "stuck"}, bounds, "allocator")
    pub.publish(diagnostics_to_msg(10 * MS, [status]))
    spin_until(executor, lambda: bool(mpc.controller._pending_bounds))
    tick(fake, executor, 10)  # the health of tick 10 is not yet for tick 10
    assert mpc.controller.mpc.radius_bounds_m is None
    tick(fake, executor, 20)
    np.testing.assert_array_equal(mpc.controller.mpc.radius_bounds_m[0], low)
    np.testing.assert_array_equal(mpc.controller.mpc.radius_bounds_m[1], high)
    swapped = {f"radius_min_{a}_m": float(v) for a, v in zip("xyz", high, strict=True)}
    pub.publish(diagnostics_to_msg(20 * MS, [replace(status, values={**status.values, **swapped})]))
    spin_until(executor, lambda: rejection_counts(mpc).get("joint_health") == 1)  # depth 1
    not_a_number = diagnostics_to_msg(20 * MS, [status])
    for kv in not_a_number.status[0].values:
        if kv.key == "radius_max_y_m":
            kv.value = "nan"
    pub.publish(not_a_number)
    spin_for(executor, 0.2)
    tick(fake, executor, 30)
    assert rejection_counts(mpc).get("joint_health") == 2
    np.testing.assert_array_equal(mpc.controller.mpc.radius_bounds_m[0], low)
    for t_ms in range(40, 110, 10):  # the next re-plan (every 100 ms) plans within them
        tick(fake, executor, t_ms)
    radii = np.asarray(mpc.controller.plan.radii)
    assert np.all(radii[:, 0] >= low[0] - 1e-6) and np.all(radii[:, 0] <= high[0] + 1e-6)
