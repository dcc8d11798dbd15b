"""Through the graph, a robot that is not the one its controllers assume (issue 27).

``spin_stabilization_robot_errors`` (masses off, a biased noisy gyro, lagging servos):
the MPC and the allocator read the flight estimator's topics, never the simulator's
ground truth; the inertia they use is the estimated model's, which differs from the
true one by what the mass error implies; and the graph flies the library loop's
flight to the last bit (noise seeded)."""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from rclpy.context import Context
from rclpy.serialization import deserialize_message

from splitter_bag.core.reader import read_messages
from splitter_bringup.analysis.summary import metric_values
from splitter_bringup.run.graph_run import run_graph_scenario
from splitter_bringup.run.inprocess import create_node
from splitter_bringup.run.library import run_closed_loop
from splitter_bringup.scenario.definition import load_scenario
from splitter_bringup.scenario.graph_config import ESTIMATOR_NODE, graph_nodes
from splitter_model.kinematics import radii_from_joint_positions
from splitter_model.model import RobotModel, principal_inertia
from splitter_msgs_py import conversions as conv
from splitter_msgs_py import names

SCENARIO = "spin_stabilization_robot_errors"
DURATION_S = 3.0  # [s] simulated
# what the simulator computes exactly and a robot cannot measure
GROUND_TRUTH = (
    *names.TRUTH_TOPICS,
    names.INERTIA,
    names.ODOM,
    *names.CONTACT_WRENCHES,
    names.SCENE_MASSES,
)
ESTIMATE_READERS = ("inertial_morphing_mpc", "ik_tether_allocator")
GAIT_NODE = "gait_phase_manager"


def _subscriptions(node_name: str) -> set[str]:
    """The topics the node of ``node_name`` subscribes to, remappings applied."""
    scenario = load_scenario(SCENARIO, "mpc")
    launch = next(n for n in graph_nodes(scenario) if n.name == node_name)
    context = Context()
    context.init()
    try:
        node = create_node(launch, context)
        try:
            return {sub.topic_name for sub in node.subscriptions}
        finally:
            node.destroy_node()
    finally:
        context.try_shutdown()


@pytest.mark.parametrize("node_name", [*ESTIMATE_READERS, ESTIMATOR_NODE, GAIT_NODE])
def test_the_controllers_read_estimates_not_ground_truth(node_name: str) -> None:
    topics = _subscriptions(node_name)
    assert not topics & set(GROUND_TRUTH), f"{node_name} reads ground truth: {topics}"
    if node_name == GAIT_NODE:  # its own sensors: IMU, rangefinders, leg load cells, encoders
        expected = {names.IMU, *names.RANGES, *names.LEG_FORCES, names.JOINT_STATES}
        assert topics - {names.CLOCK} == expected
    elif node_name == ESTIMATOR_NODE:
        # the gyro, the joint sensors, the legs' load cells (on the ground or not)
        assert topics - {names.CLOCK} == {names.IMU, names.JOINT_STATES, *names.LEG_FORCES}
    else:
        assert {names.ESTIMATE_IMU, names.ESTIMATE_INERTIA} <= topics


def _vectors(bag: Path, topic: str) -> dict[int, np.ndarray]:
    out = {}
    for record in read_messages(bag, [topic]):
        msg = deserialize_message(record.data, conv.TOPIC_MESSAGE_CLASSES[topic])
        sample = conv.vector3_from_msg(msg)
        out[sample.t_ns] = sample.vector
    return out


@pytest.mark.slow
def test_the_graph_flies_the_wrong_robot_as_the_library_loop(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("ROS_DOMAIN_ID", str(int(os.environ["ROS_DOMAIN_ID"]) + 30))
    scenario = replace(load_scenario(SCENARIO, "mpc"), duration_s=DURATION_S)
    graph = run_graph_scenario(scenario, tmp_path, in_process=True)
    library = run_closed_loop(scenario)
    # the flight, sample by sample, and every summary metric
    np.testing.assert_array_equal(graph.angular_velocity_rad_s, library.angular_velocity_rad_s)
    np.testing.assert_array_equal(graph.joint_position, library.joint_position)
    graph_metrics, library_metrics = (
        metric_values(graph, scenario),
        metric_values(library, scenario),
    )
    assert graph_metrics.keys() == library_metrics.keys()
    # the estimator's errors are figures of the run, from the bag as from the loop
    assert {"estimator_gyro_bias_error_rad_s", "estimator_mass_ratio_error"} <= graph_metrics.keys()
    assert graph_metrics["estimator_gyro_bias_error_rad_s"] < 0.002
    for key, value in graph_metrics.items():  # the bag's sums differ in the last bit at most
        assert value == pytest.approx(library_metrics[key], rel=1e-12, abs=1e-12), key

    bag = tmp_path / "mpc" / "bag"
    used, truth = _vectors(bag, names.ESTIMATE_INERTIA), _vectors(bag, names.TRUTH_INERTIA)
    masses = _vectors(bag, names.ESTIMATE_MASSES)
    assert used and set(used) <= set(truth)
    nominal = RobotModel()
    plant = scenario.robot_errors.plant_model(nominal)
    # t = 0: the controllers' inertia is the nominal model's at the encoders' radii, the
    # simulator's the heavier robot's: they differ by exactly what the masses imply
    radii = radii_from_joint_positions(nominal, library.joint_position[0])
    np.testing.assert_allclose(used[0], principal_inertia(nominal, radii), rtol=1e-12)
    np.testing.assert_allclose(truth[0], principal_inertia(plant, radii), rtol=1e-9)
    # at the end: the joint efforts have weighed the masses (the common scale too), so
    # the controllers' inertia is the true one (within 1 %), and the masses the robot's
    end = max(used)
    np.testing.assert_allclose(used[end], truth[end], rtol=0.01)
    true_masses = np.array([plant.body_mass_kg, plant.limb_mass_y_kg, plant.limb_mass_z_kg])
    np.testing.assert_allclose(masses[end], true_masses, rtol=0.02)
    nominal_masses = [nominal.body_mass_kg, nominal.limb_mass_y_kg, nominal.limb_mass_z_kg]
    assert not np.allclose(true_masses, nominal_masses, rtol=0.04)


@pytest.mark.slow
def test_the_graph_identifies_hemi_bodies_as_the_library_loop(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The hemi bodies' own moments: the simulator's inertia carries them from t = 0, the
    controllers' (point bodies at first) does not; the estimator's answer is in the bag,
    and the graph flies the library loop's flight."""
    monkeypatch.setenv("ROS_DOMAIN_ID", str(int(os.environ["ROS_DOMAIN_ID"]) + 31))
    scenario = replace(load_scenario(SCENARIO, "hemi_bodies"), duration_s=2.0)
    graph = run_graph_scenario(scenario, tmp_path, in_process=True)
    library = run_closed_loop(scenario)
    np.testing.assert_array_equal(graph.angular_velocity_rad_s, library.angular_velocity_rad_s)
    graph_metrics = metric_values(graph, scenario)
    library_metrics = metric_values(library, scenario)
    assert graph_metrics.keys() == library_metrics.keys()
    assert "estimator_hemi_inertia_error_kg_m2" in graph_metrics
    for key, value in graph_metrics.items():
        assert value == pytest.approx(library_metrics[key], rel=1e-12, abs=1e-12), key

    bag = tmp_path / "hemi_bodies" / "bag"
    used, truth = _vectors(bag, names.ESTIMATE_INERTIA), _vectors(bag, names.TRUTH_INERTIA)
    hemi = _vectors(bag, names.ESTIMATE_HEMI_INERTIA)
    nominal = RobotModel()
    plant = scenario.robot_errors.plant_model(nominal)
    own = 2.0 * np.array(scenario.robot_errors.hemi_inertia_kg_m2)
    radii = radii_from_joint_positions(nominal, library.joint_position[0])
    np.testing.assert_allclose(used[0], principal_inertia(nominal, radii), rtol=1e-12)
    np.testing.assert_allclose(truth[0], principal_inertia(plant, radii) + own, rtol=1e-9)
    np.testing.assert_array_equal(hemi[0], 0.0)
    last_ns = round(library.extras["estimate_t_s"][-1] * 1e9)  # the loop's last answer
    np.testing.assert_allclose(
        hemi[last_ns], library.extras["estimate_hemi_inertia_kg_m2"][-1], rtol=1e-12
    )
    assert abs(hemi[last_ns][0] - own[0] / 2.0) < abs(hemi[0][0] - own[0] / 2.0)
