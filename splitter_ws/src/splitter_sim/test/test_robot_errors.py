"""The simulated robot's errors: validation, the gyro, the actuators' lag, the masses flown."""

from __future__ import annotations

import math

import numpy as np
import pytest

from splitter_model.actuators import TETHER_INDEX
from splitter_model.kinematics import joint_positions_from_radii
from splitter_model.model import RobotModel
from splitter_msgs_py.parameters import config_from_values
from splitter_sim.core.robot_errors import Gyro, RobotErrors
from splitter_sim.core.settings import SimulatorSettings
from splitter_sim.core.simulator import SimConfig
from splitter_sim.core.tick import SimulatorTick

CONTROL_PERIOD_S = 0.01  # [s]
CONTROL_NS = 10_000_000  # [ns]


@pytest.mark.parametrize(
    ("changes", "field"),
    [
        ({"mass_scale": (1.0, 0.0, 1.0)}, "mass_scale"),
        ({"mass_scale": (1.0, 10.0, 1.0)}, "mass_scale"),
        ({"mass_scale": (1.0, 1.0)}, "mass_scale"),
        ({"mass_scale": (1.0, math.nan, 1.0)}, "mass_scale"),
        ({"hemi_inertia_kg_m2": (0.01, -0.01, 0.01)}, "hemi_inertia_kg_m2"),
        ({"hemi_inertia_kg_m2": (0.01, math.nan, 0.01)}, "hemi_inertia_kg_m2"),
        ({"hemi_inertia_kg_m2": (0.1, 0.02, 0.03)}, "hemi_inertia_kg_m2"),  # no such body
        ({"hemi_inertia_kg_m2": 0.1}, "hemi_inertia_kg_m2"),
        ({"gyro_noise_rad_s": -0.1}, "gyro_noise_rad_s"),
        ({"gyro_noise_rad_s": math.inf}, "gyro_noise_rad_s"),
        ({"gyro_noise_rad_s": "0.1"}, "gyro_noise_rad_s"),
        ({"gyro_bias_rad_s": (0.0, math.inf, 0.0)}, "gyro_bias_rad_s"),
        ({"gyro_bias_rad_s": "abc"}, "gyro_bias_rad_s"),
        ({"actuator_lag_s": -0.01}, "actuator_lag_s"),
        ({"actuator_lag_s": math.nan}, "actuator_lag_s"),
        ({"joint_effort_noise": -0.1}, "joint_effort_noise"),
        ({"joint_effort_noise": math.nan}, "joint_effort_noise"),
        ({"range_noise_m": -0.01}, "range_noise_m"),
        ({"command_latency_s": -0.01}, "command_latency_s"),
        ({"leg_force_noise_n": math.inf}, "leg_force_noise_n"),
        ({"accelerometer_noise_m_s2": -0.1}, "accelerometer_noise_m_s2"),
        ({"noise_seed": -1}, "noise_seed"),
        ({"noise_seed": 1.5}, "noise_seed"),
        ({"noise_seed": True}, "noise_seed"),
    ],
)
def test_an_invalid_error_is_refused_naming_its_field(changes: dict, field: str) -> None:
    with pytest.raises(ValueError, match=f"^{field}: "):
        RobotErrors(**changes)


def test_the_fields_are_normalised_and_are_node_parameters() -> None:
    errors = RobotErrors(mass_scale=[1, 2, 3], gyro_bias_rad_s=np.array([0.1, 0, 0]))
    assert errors.mass_scale == (1.0, 2.0, 3.0) and errors.gyro_bias_rad_s == (0.1, 0.0, 0.0)
    values = {"mass_scale": [1.1, 0.9, 1.0], "noise_seed": 3, "actuator_lag_s": 0.05}
    assert config_from_values(RobotErrors, values) == RobotErrors(
        mass_scale=(1.1, 0.9, 1.0), noise_seed=3, actuator_lag_s=0.05
    )


def test_the_plant_flies_the_scaled_masses() -> None:
    nominal = RobotModel()
    plant = RobotErrors(mass_scale=(1.08, 0.93, 1.05)).plant_model(nominal)
    assert plant.body_mass_kg == nominal.body_mass_kg * 1.08
    assert plant.limb_mass_y_kg == nominal.limb_mass_y_kg * 0.93
    assert plant.limb_mass_z_kg == nominal.limb_mass_z_kg * 1.05
    assert RobotErrors().plant_model(nominal) == nominal
    settings = SimulatorSettings(robot_errors=RobotErrors(mass_scale=(2.0, 1.0, 1.0)))
    sim = settings.simulator(SimConfig(ground_contact=False), nominal)
    assert sim.model.body_mass_kg == 2.0 * nominal.body_mass_kg
    nominal_sim = SimulatorSettings().simulator(SimConfig(ground_contact=False), nominal)
    # the heavier hemi bodies at the tether's ends: a larger I_y, I_z
    heavier = sim.state().principal_inertia_kg_m2
    assert heavier[1] > nominal_sim.state().principal_inertia_kg_m2[1]


def test_the_gyro_reads_the_rate_with_its_bias_and_noise() -> None:
    bias = (0.004, -0.005, 0.003)  # [rad/s]
    gyro = Gyro(RobotErrors(gyro_noise_rad_s=0.002, gyro_bias_rad_s=bias, noise_seed=7))
    w = np.array([-0.3, -0.9, 0.9])
    errors = np.array([gyro.read(w) - w for _ in range(20_000)])
    # mean within 4 standard errors of the bias, std within 3 % of the noise
    np.testing.assert_allclose(errors.mean(axis=0), bias, atol=4 * 0.002 / math.sqrt(20_000))
    np.testing.assert_allclose(errors.std(axis=0), 0.002, rtol=0.03)
    # axes independent
    assert abs(np.corrcoef(errors.T)[0, 1]) < 0.05
    # one reading = 3 normals of default_rng(noise_seed)
    rng = np.random.default_rng(7)
    again = Gyro(RobotErrors(gyro_noise_rad_s=0.002, noise_seed=7))
    np.testing.assert_array_equal(again.read(w), w + rng.normal(0.0, 0.002, 3))
    np.testing.assert_array_equal(again.read(w), w + rng.normal(0.0, 0.002, 3))


def test_a_gyro_without_noise_draws_nothing_and_without_errors_is_the_true_rate() -> None:
    gyro = Gyro(RobotErrors(gyro_bias_rad_s=(0.01, 0.0, 0.0)))
    state_before = gyro._rng.bit_generator.state
    w = np.array([-0.0, 1.0, 2.0])
    np.testing.assert_array_equal(gyro.read(w), [0.01, 1.0, 2.0])
    assert gyro._rng.bit_generator.state == state_before
    exact = Gyro(RobotErrors()).read(w)
    np.testing.assert_array_equal(exact, w)
    assert math.copysign(1.0, exact[0]) == -1.0  # bit-identical, -0.0 kept


def _tick(errors: RobotErrors) -> SimulatorTick:
    settings = SimulatorSettings(control_period_s=CONTROL_PERIOD_S, robot_errors=errors)
    return SimulatorTick(settings.simulator(SimConfig(ground_contact=False)), settings)


def test_a_command_reaches_the_servos_its_latency_after_its_stamp() -> None:
    """20 ms of latency: the goal sent at 10 ms is in force at 30 ms, not before."""
    tick = _tick(RobotErrors(command_latency_s=0.02))
    model = tick.sim.model
    start = joint_positions_from_radii(model, (2.8, 0.2, 0.2))
    goal = joint_positions_from_radii(model, (2.6, 0.3, 0.3))
    velocity = np.zeros_like(start)
    in_force = {}
    for _ in range(8):  # sim steps of 5 ms; commands every control period (10 ms)
        t = tick.time_ns
        if t % CONTROL_NS == 0:
            tick.command_joints(t, start if t == 0 else goal, velocity)
        tick.step()  # applies the points due at t, then steps over [t, t + 5 ms)
        in_force[t] = tick.sim._cmd_q.copy()
    first_goal = min(t for t, q in in_force.items() if np.array_equal(q, goal))
    assert first_goal == 30_000_000  # [ns] stamped 10 ms, 20 ms late


def test_a_step_command_reaches_the_servos_through_the_lag() -> None:
    """Sampled per control tick, the command in force is 1 - exp(-t / tau) of the step.

    ``t``: the periods since the step was sent, counting the one it is held over
    (``CommandLag``: the command sent at a tick is held over the period that follows).
    """
    tau = 0.05  # [s]
    tick = _tick(RobotErrors(actuator_lag_s=tau))
    model = tick.sim.model
    start = joint_positions_from_radii(model, (2.8, 0.2, 0.2))
    goal = joint_positions_from_radii(model, (2.6, 0.3, 0.3))
    velocity = np.zeros_like(start)
    in_force = []
    for k in range(20):
        t = tick.time_ns
        assert t == k * CONTROL_NS
        tick.command_joints(t, start if k == 0 else goal, velocity)
        in_force.append(tick.sim._cmd_q.copy())  # the servos' command point
        tick.step()
        tick.step()
    fraction = [(q - start)[TETHER_INDEX] / (goal - start)[TETHER_INDEX] for q in in_force]
    expected = [0.0] + [1.0 - math.exp(-k * CONTROL_PERIOD_S / tau) for k in range(1, 20)]
    np.testing.assert_allclose(fraction, expected, rtol=1e-12, atol=1e-12)
    # without lag the step is in force at once
    tick = _tick(RobotErrors())
    tick.command_joints(0, goal, velocity)
    np.testing.assert_array_equal(tick.sim._cmd_q, goal)


def test_the_tick_reads_the_gyro_once_per_simulated_time() -> None:
    tick = _tick(RobotErrors(gyro_noise_rad_s=0.01, gyro_bias_rad_s=(0.1, 0.0, 0.0)))
    state = tick.state()
    first = tick.gyro_reading(state)
    np.testing.assert_array_equal(tick.gyro_reading(state), first)
    assert abs(first[0] - state.angular_velocity_rad_s[0] - 0.1) < 0.05
    tick.step()
    assert not np.array_equal(tick.gyro_reading(tick.state()), first)
    nominal = _tick(RobotErrors())
    s = nominal.state()
    np.testing.assert_array_equal(nominal.gyro_reading(s), s.angular_velocity_rad_s)


def test_the_effort_sensors_read_the_true_efforts_with_their_noise() -> None:
    tick = _tick(RobotErrors(joint_effort_noise=0.05, gyro_noise_rad_s=0.01, noise_seed=4))
    state = tick.state()
    reading = tick.joint_effort_reading(state)
    np.testing.assert_array_equal(tick.joint_effort_reading(state), reading)  # once per time
    noise = reading - state.joint_effort
    assert 0.02 < float(np.std(noise)) < 0.09
    # the gyro's draws do not depend on the effort sensors (their own generator)
    alone = _tick(RobotErrors(gyro_noise_rad_s=0.01, noise_seed=4))
    np.testing.assert_array_equal(alone.gyro_reading(alone.state()), tick.gyro_reading(state))
    nominal = _tick(RobotErrors())
    s = nominal.state()
    np.testing.assert_array_equal(nominal.joint_effort_reading(s), s.joint_effort)


def test_the_rangefinders_and_leg_load_cells_read_with_their_noise() -> None:
    """Level and in flight (the nominal initial state): each rangefinder reads its hemi
    body's height, with noise on a return only; the legs push nothing."""
    tick = _tick(RobotErrors(range_noise_m=0.01, leg_force_noise_n=0.5, noise_seed=3))
    state = tick.state()
    heights = state.mass_positions_world_m[[0, 5], 2]
    readings = tick.readings(state)
    assert readings is not None
    np.testing.assert_array_equal(tick.range_reading(state), tick.range_reading(state))
    finite = heights <= 20.0
    assert finite.any()
    np.testing.assert_allclose(readings.ranges_m[finite], heights[finite], atol=0.05)
    assert not np.array_equal(readings.ranges_m[finite], heights[finite])  # noisy
    assert readings.ranges_m.dtype == np.float64  # float32 values, as the message carries
    np.testing.assert_array_equal(readings.ranges_m, readings.ranges_m.astype(np.float32))
    assert 0.0 < float(np.abs(readings.leg_forces_n).max()) < 3.0  # noise about zero push
    exact = _tick(RobotErrors())
    s = exact.state()
    assert not exact.readings(s).leg_forces_n.any()


def test_the_plant_has_the_hemi_bodies_own_inertia() -> None:
    """The controllers' model has point bodies (paper eq. 2); the robot flown adds each
    hemi body's own moments, twice (two bodies), to its inertia."""
    nominal = RobotModel()
    errors = RobotErrors(hemi_inertia_kg_m2=(0.03, 0.045, 0.04))
    assert errors.present and errors.plant_model(nominal) == nominal
    config = SimConfig(ground_contact=False)
    flown = SimulatorSettings(robot_errors=errors).simulator(config, nominal).state()
    points = SimulatorSettings().simulator(config, nominal).state()
    np.testing.assert_allclose(
        flown.principal_inertia_kg_m2 - points.principal_inertia_kg_m2,
        (0.06, 0.09, 0.08),
        rtol=1e-9,
    )


def test_the_accelerometer_reads_the_specific_force_with_its_noise() -> None:
    """The IMU's accelerometer: the true specific force plus noise, once per simulated
    time, on /splitter/imu with its variance; the truth on /splitter/truth/imu."""
    from splitter_msgs_py import names
    from splitter_sim.messages import state_messages

    errors = RobotErrors(accelerometer_noise_m_s2=0.05, gyro_noise_rad_s=0.01, noise_seed=5)
    tick = _tick(errors)
    readings = [tick.readings(tick.state())]
    for _ in range(199):
        tick.step()
        readings.append(tick.readings(tick.state()))
    state = tick.state()
    np.testing.assert_array_equal(
        tick.readings(state).specific_force_m_s2, readings[-1].specific_force_m_s2
    )
    noise = np.array([r.specific_force_m_s2 for r in readings])  # free fall in zero G: 0
    assert 0.04 < float(np.std(noise)) < 0.06 and abs(float(np.mean(noise))) < 0.01
    messages = dict(state_messages(state, readings[-1]))
    imu, truth = messages[names.IMU], messages[names.TRUTH_IMU]
    a = imu.linear_acceleration
    np.testing.assert_array_equal([a.x, a.y, a.z], readings[-1].specific_force_m_s2)
    assert imu.linear_acceleration_covariance[0] == pytest.approx(0.05**2)
    t = truth.linear_acceleration
    np.testing.assert_array_equal([t.x, t.y, t.z], state.linear_acceleration_m_s2)
    # the gyro's draws do not depend on the accelerometer (its own generator)
    alone = _tick(RobotErrors(gyro_noise_rad_s=0.01, noise_seed=5))
    first = _tick(errors)
    np.testing.assert_array_equal(
        alone.gyro_reading(alone.state()), first.gyro_reading(first.state())
    )
    exact = _tick(RobotErrors())
    s = exact.state()
    np.testing.assert_array_equal(exact.readings(s).specific_force_m_s2, s.linear_acceleration_m_s2)
