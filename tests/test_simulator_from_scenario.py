"""A scenario file sets up the simulator: initial state, Euler angles, gravity, exact time."""

from __future__ import annotations

import numpy as np

from splitter_bringup.core.closed_loop import simulator_for
from splitter_bringup.core.scenario import load_scenario


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
