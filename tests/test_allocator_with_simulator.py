"""The simulator's servos follow the allocator's commands and the tether stays taut.

Library co-simulation of the paper's spin_stabilization set-up (tumbling at
w0 = [-0.3, -0.9, 0.9] rad/s, no gravity) with two setpoint steps that move every
radius: the tether reels in 1.6 m, then out 2 m, the limbs fold and stretch.
"""

from __future__ import annotations

import numpy as np
import pytest

from splitter_bringup.run.library import simulator_for
from splitter_bringup.scenario.definition import load_scenario
from splitter_ik.core.allocator import AllocatorConfig, TetherLimbAllocator
from splitter_model.model import RobotModel, principal_inertia

MODEL = RobotModel()
STEPS = [([2.0, 0.35, 0.12], 200), ([3.0, 0.15, 0.39], 250)]  # (radii [m], ticks)


def _run(config: AllocatorConfig) -> dict[str, np.ndarray]:
    scenario = load_scenario("spin_stabilization")
    sim = simulator_for(scenario, MODEL)
    allocator = TetherLimbAllocator(MODEL, config, initial_radii_m=scenario.initial_radii_m)
    steps_per_tick = round(config.control_period_s / scenario.sim_dt_s)
    out: dict[str, list] = {"tension": [], "error": [], "momentum": [], "radii": [], "plan": []}
    for radii, ticks in STEPS:
        setpoint = principal_inertia(MODEL, radii)
        for _ in range(ticks):
            state = sim.state()
            a = allocator.allocate(state.t_ns, setpoint, state.angular_velocity_rad_s)
            sim.command_joints(a.joint_position, a.joint_velocity)  # raises if over a limit
            out["tension"].append(state.tether_tension_n)
            out["error"].append(np.abs(state.joint_position - a.joint_position))
            out["momentum"].append(state.angular_momentum_world)
            out["radii"].append(state.radii_m)
            out["plan"].append(a.radii_m)
            for _ in range(steps_per_tick):
                sim.step()
    return {k: np.array(v) for k, v in out.items()}


def test_simulator_tracks_the_commands_and_the_tether_stays_taut() -> None:
    run = _run(AllocatorConfig())
    assert np.min(run["tension"]) > 0.0  # never slack, in the simulator's own dynamics
    # the reference is continuous, so the servos follow within one sim step of motion
    assert np.max(run["error"][:, 24]) < 2e-3  # [m] tether
    assert np.max(run["error"][:, :24]) < 2e-3  # [rad] limb joints
    # the setpoints are reached
    np.testing.assert_allclose(run["radii"][-1], STEPS[-1][0], atol=1e-3)
    # torque-free: world angular momentum conserved while the shape changes
    momentum = run["momentum"]
    assert np.max(np.abs(momentum - momentum[0])) < 1e-6 * np.linalg.norm(momentum[0])


@pytest.mark.parametrize(
    ("config", "failure"),
    [
        (AllocatorConfig(limb_acceleration_fraction=1.0), "slack"),
        (AllocatorConfig(tether_acceleration_fraction=1.0), "overshoot"),
    ],
)
def test_without_servo_headroom_the_simulation_suffers(
    config: AllocatorConfig, failure: str
) -> None:
    """Why the defaults keep acceleration headroom: the same run at the full limits."""
    run = _run(config)
    if failure == "slack":
        assert np.min(run["tension"]) < 0.0
    else:
        assert np.max(run["error"][:, 24]) > 0.02  # [m] the reel overshoots its stop
