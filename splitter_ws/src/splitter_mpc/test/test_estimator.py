"""The flight estimator against a torque-free flight of a robot with other masses."""

import numpy as np
import pytest

from splitter_model.model import RobotModel, principal_inertia, with_masses
from splitter_mpc.core.estimator import EstimatorConfig, FlightEstimator, model_with_log_masses

DT_S = 0.01  # [s] control tick
SUBSTEPS = 20  # truth integrated at 0.5 ms


def _radii(t_s: float) -> np.ndarray:
    """A morphing shape: tether and limbs move as the MPC moves them [m]."""
    return np.array(
        [
            2.2 + 0.5 * np.sin(0.7 * t_s),
            0.27 + 0.08 * np.sin(1.3 * t_s),
            0.25 + 0.1 * np.cos(0.9 * t_s),
        ]
    )


def _fly(plant: RobotModel, w0, duration_s: float):
    """Body rates of torque-free flight at each tick (RK4 of dh/dt = -w x h, h = I(t) w)."""
    h = principal_inertia(plant, _radii(0.0)) * np.asarray(w0, dtype=float)
    rates = [h / principal_inertia(plant, _radii(0.0))]
    dt = DT_S / SUBSTEPS
    t = 0.0
    for _ in range(round(duration_s / DT_S)):
        for _ in range(SUBSTEPS):

            def f(hh, tt):
                return -np.cross(hh / principal_inertia(plant, _radii(tt)), hh)

            k1 = f(h, t)
            k2 = f(h + 0.5 * dt * k1, t + 0.5 * dt)
            k3 = f(h + 0.5 * dt * k2, t + 0.5 * dt)
            k4 = f(h + dt * k3, t + dt)
            h = h + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
            t += dt
        rates.append(h / principal_inertia(plant, _radii(t)))
    return np.array(rates)


def _estimate(plant: RobotModel, bias, noise: float, duration_s: float = 8.0, seed: int = 1):
    rates = _fly(plant, (0.4, 0.9, -0.5), duration_s)
    rng = np.random.default_rng(seed)
    estimator = FlightEstimator(RobotModel(), EstimatorConfig())
    for k, w in enumerate(rates):
        gyro = w + np.asarray(bias) + rng.normal(0.0, noise, 3)
        t_ns = k * round(DT_S * 1e9)
        if k == 0:
            estimator.start(t_ns, gyro, _radii(0.0), (1.0, 0.0, 0.0, 0.0))
        estimate = estimator.update(t_ns, gyro, _radii(k * DT_S))
    return estimate, rates[-1]


def _scaled(scale) -> RobotModel:
    """The nominal robot with m_x, m_y, m_z scaled."""
    m = RobotModel()
    nominal = np.array([m.body_mass_kg, m.limb_mass_y_kg, m.limb_mass_z_kg])
    return with_masses(m, nominal * np.asarray(scale))


def _true_ratios(plant: RobotModel) -> np.ndarray:
    return np.array(
        [plant.limb_mass_y_kg / plant.body_mass_kg, plant.limb_mass_z_kg / plant.body_mass_kg]
    )


def test_gyro_bias_and_mass_ratios_are_found_in_a_morphing_tumble():
    plant = _scaled((1.08, 0.92, 1.05))
    bias = np.array([0.004, -0.005, 0.003])
    estimate, w_end = _estimate(plant, bias, noise=0.002)
    np.testing.assert_array_less(np.abs(estimate.gyro_bias_rad_s - bias), 0.001)
    np.testing.assert_array_less(np.abs(estimate.mass_ratios / _true_ratios(plant) - 1.0), 0.03)
    np.testing.assert_array_less(np.abs(estimate.angular_velocity_rad_s - w_end), 0.002)
    # the covariance says so too (1-sigma of the bias below the error bound)
    assert np.all(estimate.bias_std_rad_s < 0.001)


def test_a_common_mass_scale_is_not_an_error_of_the_ratios():
    """From the gyro alone (no joint efforts) the common scale stays at its prior."""
    nominal = RobotModel()
    heavier = _scaled((1.1, 1.1, 1.1))
    estimate, _ = _estimate(heavier, np.zeros(3), noise=0.0005)
    np.testing.assert_allclose(estimate.mass_ratios, _true_ratios(nominal), rtol=0.01)
    # the inertia the controllers use: the true one over the unobservable scale
    ratio = estimate.principal_inertia_kg_m2 / principal_inertia(heavier, _radii(8.0))
    np.testing.assert_allclose(ratio, 1.0 / 1.1, rtol=0.01)


def test_log_masses_scale_each_mass():
    nominal = RobotModel()
    model = model_with_log_masses(nominal, (0.0, np.log(1.2), np.log(0.9)))
    assert model.body_mass_kg == nominal.body_mass_kg
    assert model.limb_mass_y_kg == pytest.approx(1.2 * nominal.limb_mass_y_kg)
    assert model.limb_mass_z_kg == pytest.approx(0.9 * nominal.limb_mass_z_kg)


def test_update_before_start_and_backwards_time_are_refused():
    estimator = FlightEstimator(RobotModel())
    with pytest.raises(RuntimeError, match="before start"):
        estimator.update(0, np.zeros(3), _radii(0.0))
    estimator.start(10, np.zeros(3), _radii(0.0), (1.0, 0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="went back"):
        estimator.update(5, np.zeros(3), _radii(0.0))


def test_effort_model_of_a_steady_spin_is_the_centripetal_load() -> None:
    """Rigid spin w about y: the tether holds a hemi on its circle, T = m_hemi r_x w^2;
    the y limbs, spinning in their own axis' direction, feel only the x pull."""
    from splitter_model.joints import TETHER_INDEX, limb_joints, limbs_along
    from splitter_model.kinematics import joint_positions_from_radii, limb_jacobian
    from splitter_mpc.core.estimator import (
        JointReading,
        effort_coefficients,
        mass_motion,
        nominal_masses,
    )

    model, w, radii = RobotModel(), 0.9, (2.1, 0.3, 0.22)
    motion = mass_motion(model, JointReading(joint_positions_from_radii(model, radii)))
    coefficients = effort_coefficients(motion, np.zeros((10, 3)), (0.0, w, 0.0), np.zeros(3))
    masses = nominal_masses(model)
    effort = coefficients @ masses
    hemi = masses[0] + 2.0 * masses[1] + 2.0 * masses[2]
    assert effort[TETHER_INDEX] == pytest.approx(hemi * radii[0] * w**2, rel=1e-12)
    for limb in limbs_along("y"):
        q = joint_positions_from_radii(model, radii)[limb_joints(limb)]
        x = radii[0] if limb < 4 else -radii[0]
        force = masses[1] * np.array([-(w**2) * x, 0.0, 0.0])
        np.testing.assert_allclose(
            effort[limb_joints(limb)], limb_jacobian(model, limb, q).T @ force, atol=1e-12
        )


@pytest.mark.parametrize(
    ("rate", "leg_force_n"),
    [((0.0, 0.9, 0.3), 15.0), ((0.0, 0.01, 0.0), 0.0)],
    ids=["stance", "no spin"],
)
def test_efforts_weigh_nothing_on_the_ground_or_without_a_spin(rate, leg_force_n) -> None:
    """On its legs (a load cell above the threshold) the flight model does not hold; without
    a spin the efforts carry no centripetal load: efforts far from any mass model then
    leave the masses (and, on the ground, the bias) where they were."""
    from splitter_model.kinematics import joint_positions_from_radii
    from splitter_mpc.core.estimator import JointReading
    from splitter_mpc.core.estimator_tick import EstimatorTick, GyroSample

    model = RobotModel()
    tick = EstimatorTick(model)
    joints = JointReading(
        joint_positions_from_radii(model, (2.0, 0.3, 0.2)), np.zeros(25), np.full(25, 5.0)
    )
    legs = np.array([[0.0, 0.0, leg_force_n]] * 2)
    gyro = GyroSample(np.asarray(rate), np.array([1.0, 0.0, 0.0, 0.0]))
    first = tick.on_sensors(0, gyro, joints, legs)
    for k in range(1, 30):
        last = tick.on_sensors(k * 10_000_000, gyro, joints, legs)
    assert tick.estimator.effort_updates == 0
    np.testing.assert_array_equal(last.masses_kg, first.masses_kg)
    if leg_force_n > 0.0:  # the rate follows the gyro; the bias barely moves (1e-6 rad/s)
        np.testing.assert_allclose(last.gyro_bias_rad_s, first.gyro_bias_rad_s, atol=1e-6)


def test_a_servo_swinging_about_its_setpoint_weighs_nothing() -> None:
    """The reel at 1.3 m/s swings about its setpoint: its encoder velocity zig-zags, so the
    central difference around a tick cancels while the servo accelerates hard at it, and
    its tension (25 N, -11 N, ...) is the reel's acceleration, not the masses. Such ticks
    are skipped (the masses end where the gyro alone puts them); the same reel moving
    steadily is weighed at every tick that has both neighbours."""
    from splitter_model.joints import TETHER_INDEX
    from splitter_model.kinematics import joint_positions_from_radii
    from splitter_mpc.core.estimator import (
        JointReading,
        effort_coefficients,
        mass_motion,
        nominal_masses,
    )

    model = RobotModel()
    rate = np.array([0.0, 0.4, 0.1])  # [rad/s]

    def run(reel: str) -> FlightEstimator:
        estimator = FlightEstimator(model, EstimatorConfig())
        for k in range(12):
            radii = (5.0 - 0.013 * k, 0.3, 0.2)  # [m]
            swing = (-1) ** k if reel == "swinging" else 0.0
            velocity = np.zeros(25)
            velocity[TETHER_INDEX] = -1.3 + 0.012 * swing  # [m/s]
            position = joint_positions_from_radii(model, radii)
            motion = mass_motion(model, JointReading(position, velocity))
            effort = effort_coefficients(motion, np.zeros((10, 3)), rate, np.zeros(3))
            effort = effort @ nominal_masses(model)
            effort[TETHER_INDEX] += 18.0 * swing  # [N] the servo's own +-1.2 m/s^2
            joints = JointReading(position, velocity, effort)
            t_ns = k * 10_000_000
            if k == 0:
                estimator.start(t_ns, rate, radii, (1.0, 0.0, 0.0, 0.0))
            estimator.update(t_ns, rate, radii, joints=None if reel == "none" else joints)
        return estimator

    swinging, steady, gyro_only = run("swinging"), run("steady"), run("none")
    assert swinging.effort_updates == 0
    np.testing.assert_array_equal(swinging.estimate().masses_kg, gyro_only.estimate().masses_kg)
    assert steady.effort_updates == 10


def test_the_hemi_bodies_moments_are_states_only_when_asked_for() -> None:
    """Prior std 0 (the default): the paper's point bodies, 9 states; > 0: 12, and the
    inertia the estimator answers is eq. (2) of its masses plus both bodies' moments."""
    radii = _radii(0.0)
    points = FlightEstimator(RobotModel())
    points.start(0, (0.1, 0.9, -0.4), radii, (1.0, 0.0, 0.0, 0.0))
    assert points.estimate().covariance.shape == (9, 9)
    np.testing.assert_array_equal(points.estimate().hemi_inertia_kg_m2, 0.0)
    bodies = FlightEstimator(RobotModel(), EstimatorConfig(hemi_inertia_prior_kg_m2=0.05))
    bodies.start(0, (0.1, 0.9, -0.4), radii, (1.0, 0.0, 0.0, 0.0))
    for k in range(1, 50):
        estimate = bodies.update(k * 10_000_000, (0.1, 0.9, -0.4), _radii(k * DT_S))
    assert estimate.covariance.shape == (12, 12)
    assert np.all(np.sqrt(np.diag(estimate.covariance)[9:]) <= 0.05)
    np.testing.assert_allclose(
        estimate.principal_inertia_kg_m2,
        principal_inertia(bodies.estimated_model(), _radii(49 * DT_S))
        + 2.0 * estimate.hemi_inertia_kg_m2,
        rtol=1e-12,
    )
