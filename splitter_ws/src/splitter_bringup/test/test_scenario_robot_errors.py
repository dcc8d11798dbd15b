"""A scenario's ``robot_errors``: parsed with errors naming the field, given to the simulator
node as parameters and to the library loop's simulator tick alike."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from splitter_bringup.scenario.definition import ScenarioError, load_scenario
from splitter_bringup.scenario.graph_config import (
    ESTIMATOR_NODE,
    graph_nodes,
    simulator_parameters,
)
from splitter_bringup.scenario.simulation import simulator_tick
from splitter_model.model import RobotModel
from splitter_mpc.core.estimator import EstimatorConfig
from splitter_msgs_py.parameters import config_from_values, specs_from_config
from splitter_sim.core.robot_errors import RobotErrors

NAME = "spin_stabilization_robot_errors"
ERRORS = RobotErrors(
    mass_scale=(1.08, 0.93, 1.05),
    gyro_noise_rad_s=0.002,
    gyro_bias_rad_s=(0.004, -0.005, 0.003),
    actuator_lag_s=0.05,
    joint_effort_noise=0.05,
    noise_seed=7,
)


def test_the_robot_errors_scenario_loads_as_spin_stabilization_with_errors() -> None:
    scenario = load_scenario(NAME)
    assert scenario.robot_errors == ERRORS
    base = load_scenario("spin_stabilization")
    assert base.robot_errors == RobotErrors()
    # spin_stabilization's variants, then the hemi bodies' (flown as "mpc" is)
    assert scenario.variants == (*base.variants, "hemi_bodies", "hemi_bodies_as_points")
    for variant in ("hemi_bodies", "hemi_bodies_as_points"):
        assert load_scenario(NAME, variant).controller == load_scenario(NAME, "mpc").controller
    for variant in base.variants:  # a copy of spin_stabilization but for the errors
        a, b = load_scenario(NAME, variant), load_scenario("spin_stabilization", variant)
        assert a.controller == b.controller and a.duration_s == b.duration_s
        np.testing.assert_array_equal(
            a.initial_angular_velocity_rad_s, b.initial_angular_velocity_rad_s
        )


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ("robot_errors: 3", "robot_errors: expected a mapping"),
        ("robot_errors: {mass_scale: [1, 1]}", r"robot_errors\.mass_scale: 3 finite numbers"),
        ("robot_errors: {mass_scale: [1, 0, 1]}", r"robot_errors\.mass_scale: each factor"),
        (
            "robot_errors: {gyro_bias_rad_s: [0, .nan, 0]}",
            r"robot_errors\.gyro_bias_rad_s: 3 finite numbers",
        ),
        ("robot_errors: {gyro_noise_rad_s: -1}", r"robot_errors\.gyro_noise_rad_s: must be"),
        ("robot_errors: {actuator_lag_s: abc}", r"robot_errors\.actuator_lag_s: a number"),
        ("robot_errors: {noise_seed: 1.5}", r"robot_errors\.noise_seed: an integer"),
        (
            "robot_errors: {joint_effort_noise: -0.1}",
            r"robot_errors\.joint_effort_noise: must be",
        ),
        ("robot_errors: {gyro_drift: 1}", r"robot_errors\.gyro_drift: unknown field"),
        (
            "robot_errors: {hemi_inertia_kg_m2: [0.1, 0.01, 0.01]}",
            r"robot_errors\.hemi_inertia_kg_m2: no rigid body",
        ),
        ("estimator: 3", "estimator: expected a mapping"),
        ("estimator: {gyro_drift: 1}", r"estimator\.gyro_drift: unknown field"),
        (
            "estimator: {hemi_inertia_prior_kg_m2: -0.1}",
            r"estimator\.hemi_inertia_prior_kg_m2: .* must be >= 0",
        ),
        ("estimator: {gyro_noise_rad_s: .nan}", r"estimator\.gyro_noise_rad_s: .* finite"),
        ("estimator: {use_joint_effort: 1}", r"estimator\.use_joint_effort: .* bool"),
    ],
)
def test_a_bad_robot_error_names_its_field(tmp_path: Path, entry: str, message: str) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text(f"duration_s: 1.0\n{entry}\n")
    with pytest.raises(ScenarioError, match=message):
        load_scenario(bad)


def test_the_node_parameters_and_the_library_tick_carry_the_same_errors() -> None:
    scenario = load_scenario(NAME)
    values = simulator_parameters(scenario, real_time=False, rate_factor=1.0)
    declared = {spec.name for spec in specs_from_config(RobotErrors)}
    assert declared <= set(values)
    assert config_from_values(RobotErrors, values) == ERRORS
    tick = simulator_tick(scenario)
    assert tick.errors == ERRORS
    nominal = RobotModel()
    assert tick.sim.model == ERRORS.plant_model(nominal)
    assert tick.sim.model.body_mass_kg == pytest.approx(1.08 * nominal.body_mass_kg)


def test_the_estimator_section_reaches_the_node_and_the_library_alike() -> None:
    scenario = load_scenario(NAME, "hemi_bodies")
    assert scenario.estimator == EstimatorConfig(hemi_inertia_prior_kg_m2=0.05)
    assert scenario.robot_errors.hemi_inertia_kg_m2 == (0.03, 0.045, 0.04)
    assert scenario.robot_errors.mass_scale == ERRORS.mass_scale  # merged over the base
    estimator = next(n for n in graph_nodes(scenario) if n.name == ESTIMATOR_NODE)
    assert config_from_values(EstimatorConfig, estimator.parameters) == scenario.estimator
    assert load_scenario(NAME).estimator == EstimatorConfig()


def test_without_errors_the_library_tick_is_the_nominal_simulator() -> None:
    from splitter_bringup.run.library import simulator_for

    scenario = load_scenario("lunar_jumping")
    tick, library = simulator_tick(scenario), simulator_for(scenario)
    assert tick.sim.config == library.config and tick.sim.model == library.model
    for _ in range(3):
        a, b = tick.state(), library.state()
        for name in ("position_m", "orientation_wxyz", "angular_velocity_rad_s", "joint_position"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        np.testing.assert_array_equal(tick.gyro_reading(a), b.angular_velocity_rad_s)
        tick.step()
        library.step()
