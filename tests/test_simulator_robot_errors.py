"""Through ROS: the simulator node of a scenario with robot errors publishes what its gyro
reads on /splitter/imu and the ground truth on /splitter/truth/imu and /splitter/truth/inertia,
exactly as the library loop's simulator tick computes them."""

from __future__ import annotations

import time
from collections import defaultdict

import numpy as np
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter

from splitter_bringup.scenario.definition import load_scenario
from splitter_bringup.scenario.graph_config import simulator_parameters
from splitter_bringup.scenario.simulation import simulator_tick
from splitter_model.model import RobotModel
from splitter_msgs_py import conversions as conv
from splitter_msgs_py import names
from splitter_msgs_py.qos import qos_for
from splitter_msgs_py.testing import spin_until
from splitter_sim.simulator_node import SimulatorNode

DURATION_S = 0.2  # [s] simulated: 41 states of 5 ms
TOPICS = (names.IMU, names.TRUTH_IMU, names.INERTIA, names.TRUTH_INERTIA)
# a lone simulator: nothing to wait for (in-process discovery is immediate)
ALONE = {"startup_wait_s": 0.5, "duration_s": DURATION_S}
WAITS = ("startup_wait_for_nodes", "startup_wait_for_publishers")  # no controllers here


class Probe(Node):
    """Keeps every message of ``TOPICS``."""

    def __init__(self, **kwargs) -> None:
        super().__init__("probe", **kwargs)
        self.messages: dict[str, list] = defaultdict(list)
        for topic in TOPICS:
            self.create_subscription(
                conv.TOPIC_MESSAGE_CLASSES[topic],
                topic,
                lambda msg, topic=topic: self.messages[topic].append(msg),
                qos_for(topic),
            )


def _run(ros_context, scenario) -> Probe:
    values = {**simulator_parameters(scenario, real_time=False, rate_factor=1.0), **ALONE}
    values = {k: v for k, v in values.items() if k not in WAITS and v != []}
    executor = SingleThreadedExecutor(context=ros_context)
    probe = Probe(context=ros_context)
    sim = SimulatorNode(
        context=ros_context, parameter_overrides=[Parameter(k, value=v) for k, v in values.items()]
    )
    try:
        for node in (probe, sim):
            executor.add_node(node)
        spin_until(executor, sim.finished.done, 30.0)
        n = round(DURATION_S / scenario.sim_dt_s) + 1
        deadline = time.monotonic() + 10.0
        while any(len(probe.messages[t]) < n for t in TOPICS) and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.01)
    finally:
        for node in (probe, sim):
            executor.remove_node(node)
        sim.destroy_node()
        executor.shutdown()
    return probe


def test_the_imu_carries_the_gyro_errors_and_the_truth_topics_the_exact_state(ros_context) -> None:
    scenario = load_scenario("spin_stabilization_robot_errors")
    errors = scenario.robot_errors
    probe = _run(ros_context, scenario)
    n = round(DURATION_S / scenario.sim_dt_s) + 1
    for topic in TOPICS:
        assert len(probe.messages[topic]) == n, topic
    imu = [conv.imu_from_msg(m) for m in probe.messages[names.IMU]]
    truth = [conv.imu_from_msg(m) for m in probe.messages[names.TRUTH_IMU]]
    assert [s.t_ns for s in imu] == [s.t_ns for s in truth]
    measured = np.array([s.angular_velocity_rad_s for s in imu])
    exact = np.array([s.angular_velocity_rad_s for s in truth])
    error = measured - exact
    sigma = errors.gyro_noise_rad_s
    # the bias, within the noise of the mean of n readings
    np.testing.assert_allclose(error.mean(axis=0), errors.gyro_bias_rad_s, atol=5 * sigma / n**0.5)
    assert 0.5 * sigma < float(np.std(error - error.mean(axis=0))) < 1.5 * sigma
    cov = np.array(probe.messages[names.IMU][0].angular_velocity_covariance)
    np.testing.assert_allclose(cov.reshape(3, 3), np.eye(3) * sigma**2)
    assert not np.any(probe.messages[names.TRUTH_IMU][0].angular_velocity_covariance)
    # the attitude stays the true one (the estimator's, later)
    np.testing.assert_array_equal(
        [s.orientation_wxyz for s in imu], [s.orientation_wxyz for s in truth]
    )
    # the library loop's tick computes the same: exact state, gyro readings (one per step)
    tick = simulator_tick(scenario)
    inertia = [conv.vector3_from_msg(m).vector for m in probe.messages[names.TRUTH_INERTIA]]
    for k in range(n):
        state = tick.state()
        np.testing.assert_array_equal(exact[k], state.angular_velocity_rad_s)
        np.testing.assert_array_equal(measured[k], tick.gyro_reading(state))
        np.testing.assert_array_equal(inertia[k], state.principal_inertia_kg_m2)
        tick.step()
    # the true inertia is the plant's (masses scaled), not the nominal robot's
    nominal = simulator_tick(load_scenario("spin_stabilization"), RobotModel()).state()
    assert abs(inertia[0][1] - nominal.principal_inertia_kg_m2[1]) > 1.0  # [kg m^2]
    # /splitter/inertia is still the truth for now (the estimator will take it over)
    np.testing.assert_array_equal(
        [conv.vector3_from_msg(m).vector for m in probe.messages[names.INERTIA]], inertia
    )
