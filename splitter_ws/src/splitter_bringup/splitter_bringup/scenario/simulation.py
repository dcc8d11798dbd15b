"""The simulator of a scenario as the library loop drives it: the graph's, without ROS.

ROS-free. :func:`simulator_tick` builds the
:class:`~splitter_sim.core.tick.SimulatorTick` the ``simulator`` node would run for
the scenario (the same initial state, step, gravity, ground, and the scenario's
``robot_errors``: the masses flown, the gyro's bias and noise, the actuators' lag),
for a closed loop that calls it directly (``splitter_bringup.run.library``).
"""

from __future__ import annotations

from splitter_bringup.scenario.definition import Scenario
from splitter_model.faults import fault_parameters
from splitter_model.model import RobotModel
from splitter_sim.core.settings import SimulatorSettings
from splitter_sim.core.simulator import SimConfig
from splitter_sim.core.tick import SimulatorTick

CONTROL_PERIOD_S = 0.01  # [s] the control tick (docs/ARCHITECTURE.md)


def _three(values) -> tuple[float, float, float]:
    return (float(values[0]), float(values[1]), float(values[2]))


def simulator_settings(
    scenario: Scenario, control_period_s: float = CONTROL_PERIOD_S
) -> SimulatorSettings:
    """The simulator node's settings of ``scenario``: initial state and robot errors."""
    return SimulatorSettings(
        control_period_s=float(control_period_s),
        initial_position_m=_three(scenario.initial_position_m),
        initial_velocity_m_s=_three(scenario.initial_velocity_m_s),
        initial_orientation_euler_deg=_three(scenario.initial_orientation_euler_deg),
        initial_angular_velocity_rad_s=_three(scenario.initial_angular_velocity_rad_s),
        initial_radii_m=_three(scenario.initial_radii_m),
        robot_errors=scenario.robot_errors,
    )


def sim_config(scenario: Scenario) -> SimConfig:
    """The physics settings of ``scenario`` (step, gravity, ground, legs)."""
    return SimConfig(
        dt_s=float(scenario.sim_dt_s),
        gravity_m_s2=float(scenario.gravity_m_s2),
        ground_contact=bool(scenario.ground_contact),
        compliant_legs=bool(scenario.compliant_legs),
        leg_cone_half_angle_deg=float(scenario.leg_cone_half_angle_deg),
        leg_posture_stiffness_n_m=float(scenario.leg_posture_stiffness_n_m),
        leg_ride_height_m=float(scenario.leg_ride_height_m),
        friction_coefficient=float(scenario.friction_coefficient),
        ground_slope_deg=float(scenario.terrain.slope_deg),
        ground_slope_azimuth_deg=float(scenario.terrain.slope_azimuth_deg),
        ground_steps_m=scenario.terrain.steps_flat(),
        **fault_parameters(scenario.faults),
    )


def simulator_tick(
    scenario: Scenario,
    model: RobotModel | None = None,
    control_period_s: float = CONTROL_PERIOD_S,
) -> SimulatorTick:
    """The simulator of ``scenario`` and its tick, flying its ``robot_errors``.

    ``model`` is the nominal robot (default :class:`RobotModel`); the simulator flies
    it with the scenario's masses (``RobotErrors.plant_model``), lags every joint
    command through ``CommandLag(actuator_lag_s, control_period_s)`` and its
    :meth:`~SimulatorTick.gyro_reading` carries the gyro's bias and noise. Without
    robot errors it is exactly the nominal simulator.
    """
    settings = simulator_settings(scenario, control_period_s)
    return SimulatorTick(settings.simulator(sim_config(scenario), model), settings)
