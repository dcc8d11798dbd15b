"""A scenario file sets up the simulator: initial state, Euler angles, gravity, exact time."""

from __future__ import annotations

import numpy as np

from splitter_bringup.run.library import simulator_for
from splitter_bringup.scenario.definition import load_scenario


def test_a_scenario_sets_up_the_simulator_with_integer_time() -> None:
    scenario = load_scenario("orientation_tracking")
    sim = simulator_for(scenario)
    s = sim.state()
    np.testing.assert_allclose(s.angular_velocity_rad_s, [0.5, -0.5, 0.5])
    # scipy "xyz" (extrinsic) Euler angles [5, 5, 15] deg
    w, x, y, z = s.orientation_wxyz
    from scipy.spatial.transform import Rotation

    np.testing.assert_allclose(
        Rotation.from_quat([x, y, z, w]).as_euler("xyz", degrees=True), [5.0, 5.0, 15.0]
    )
    assert sim.config.gravity_m_s2 == 0.0 and not sim.config.ground_contact
    for _ in range(1000):
        sim.step()
    assert sim.time_ns == 1000 * 5_000_000  # exact integer nanoseconds, no drift
    assert sim.state().t_ns == sim.time_ns


def test_the_node_parameters_of_a_scenario_build_the_library_simulator() -> None:
    """The graph's simulator (its parameters through SimConfig and SimulatorSettings, the
    fields the node declares) starts where the library loop's does, with the same config."""
    from splitter_bringup.scenario.graph_config import simulator_parameters
    from splitter_model.model import gravity_from_name
    from splitter_msgs_py.parameters import config_from_values
    from splitter_sim.core.settings import SimulatorSettings
    from splitter_sim.core.simulator import SimConfig

    scenario = load_scenario("lunar_jumping")
    values = simulator_parameters(scenario, real_time=False, rate_factor=1.0)
    settings = config_from_values(SimulatorSettings, values)
    config = config_from_values(
        SimConfig, values, gravity_m_s2=gravity_from_name(values["gravity"])
    )
    node_state = settings.simulator(config).state()
    library = simulator_for(scenario)
    assert config == library.config
    for name in ("position_m", "orientation_wxyz", "angular_velocity_rad_s", "joint_position"):
        np.testing.assert_array_equal(getattr(node_state, name), getattr(library.state(), name))
