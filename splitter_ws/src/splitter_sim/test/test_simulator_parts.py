"""The simulator's parts: actuator servo, shape kinematics, contact law, configuration."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from splitter_model.actuators import TETHER_INDEX, actuator_limits
from splitter_model.kinematics import (
    joint_positions_from_radii,
    limb_offsets_from_joint_positions,
    radii_from_joint_positions,
)
from splitter_model.model import (
    RobotModel,
    center_of_mass,
    inertia_tensor,
    lumped_mass_positions,
    principal_inertia,
)
from splitter_sim.core import actuators
from splitter_sim.core.contact import ground_contact_force
from splitter_sim.core.shape import ShapeKinematics
from splitter_sim.core.simulator import InitialState, SimConfig, Simulator

MODEL = RobotModel()
LIMITS = actuator_limits(MODEL)
DT = 0.005  # [s]


# --- actuators ---------------------------------------------------------------------------
def _random_command(rng: np.random.Generator) -> np.ndarray:
    return rng.uniform(LIMITS.position_min, LIMITS.position_max)


def test_servo_respects_every_limit_and_arrives_exactly_at_rest() -> None:
    rng = np.random.default_rng(7)
    q = joint_positions_from_radii(MODEL, (2.8, 0.2, 0.2))
    qd = np.zeros(25)
    for _ in range(4):
        target = _random_command(rng)
        zero = np.zeros(25)
        for _ in range(int(6.0 / DT)):
            qdd = actuators.servo_acceleration(q, qd, target, zero, LIMITS, DT)
            assert np.all(np.abs(qdd) <= LIMITS.acceleration_max * (1 + 1e-12))
            q, qd = actuators.advance(q, qd, qdd, DT)
            assert np.all(np.abs(qd) <= LIMITS.speed_max * (1 + 1e-12))
            # Never beyond the target (no overshoot), hence never beyond a joint limit.
            assert np.all(q >= LIMITS.position_min - 1e-9)
            assert np.all(q <= LIMITS.position_max + 1e-9)
            actuators.snap_arrived(q, qd, target, zero)
        np.testing.assert_array_equal(q, target)
        np.testing.assert_array_equal(qd, 0.0)


def test_servo_reaches_the_full_speed_on_a_long_move() -> None:
    q = joint_positions_from_radii(MODEL, (2.8, 0.2, 0.2))
    target = joint_positions_from_radii(MODEL, (1.0, 0.2, 0.2))
    qd = np.zeros(25)
    top = 0.0
    for _ in range(400):
        qdd = actuators.servo_acceleration(q, qd, target, np.zeros(25), LIMITS, DT)
        q, qd = actuators.advance(q, qd, qdd, DT)
        top = max(top, abs(qd[TETHER_INDEX]))
    assert top == pytest.approx(MODEL.tether_speed_max_m_s, rel=1e-12)


def test_servo_tracks_a_moving_target_without_lag() -> None:
    q = np.zeros(25) + 0.5
    qd = np.zeros(25)
    speed = 0.5 * LIMITS.speed_max  # [rad/s] (tether: m/s)
    for k in range(200):
        t = k * DT
        target = 0.5 + speed * t
        qdd = actuators.servo_acceleration(q, qd, target, speed, LIMITS, DT)
        q, qd = actuators.advance(q, qd, qdd, DT)
    np.testing.assert_allclose(q, 0.5 + speed * 200 * DT, atol=1e-9)
    np.testing.assert_allclose(qd, speed, atol=1e-9)


@pytest.mark.parametrize(
    ("index", "value", "message"),
    [
        (2, math.nan, "hemi_a_y_pos_knee"),
        (24, 7.0, "tether"),
        (5, 0.1, "hemi_a_y_neg_knee"),  # below the knee's 0.25 rad
        (3, math.inf, "hemi_a_y_neg_hip_abduction"),
    ],
)
def test_invalid_commands_raise_naming_the_joint_and_keep_the_last_good(
    index: int, value: float, message: str
) -> None:
    sim = Simulator(MODEL, SimConfig(ground_contact=False), InitialState(position_m=(0, 0, 10)))
    good = joint_positions_from_radii(MODEL, (2.5, 0.3, 0.3))
    sim.command_joints(good)
    bad = good.copy()
    bad[index] = value
    with pytest.raises(ValueError, match=message):
        sim.command_joints(bad)
    with pytest.raises(ValueError, match="25 values"):
        sim.command_joints(good[:TETHER_INDEX])
    with pytest.raises(ValueError, match="velocity"):
        sim.command_joints(good, np.full(25, 1e3))
    for _ in range(800):
        sim.step()
    np.testing.assert_array_equal(sim.state().joint_position, good)


# --- shape -----------------------------------------------------------------------------
@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_shape_matches_the_shared_kinematics_and_its_derivatives(seed: int) -> None:
    rng = np.random.default_rng(seed)
    q = _random_command(rng)
    qd = rng.normal(0.0, 2.0, 25)
    qdd = rng.normal(0.0, 20.0, 25)
    kin = ShapeKinematics(MODEL)
    shape = kin.evaluate(q.tolist(), qd.tolist(), qdd.tolist())
    geometric = lumped_mass_positions(
        [q[TETHER_INDEX] / 2.0, 0.0, 0.0], limb_offsets_from_joint_positions(MODEL, q)
    )
    com = center_of_mass(MODEL.lumped_masses_kg, geometric)
    np.testing.assert_allclose(shape.positions(), geometric - com, atol=1e-14)
    np.testing.assert_allclose(
        shape.inertia_matrix(), inertia_tensor(MODEL.lumped_masses_kg, geometric), atol=1e-12
    )
    # Time derivatives along q(t) = q + qd t + qdd t^2 / 2, central differences.
    eps = 1e-5
    ahead = kin.evaluate((q + eps * qd + 0.5 * eps**2 * qdd).tolist(), (qd + eps * qdd).tolist())
    behind = kin.evaluate((q - eps * qd + 0.5 * eps**2 * qdd).tolist(), (qd - eps * qdd).tolist())
    np.testing.assert_allclose(
        (ahead.positions() - behind.positions()) / (2 * eps), shape.velocities(), atol=1e-7
    )
    np.testing.assert_allclose(
        (ahead.velocities() - behind.velocities()) / (2 * eps), shape.accelerations(), atol=1e-5
    )
    np.testing.assert_allclose(
        (ahead.inertia_matrix() - behind.inertia_matrix()) / (2 * eps),
        np.array(
            [
                [shape.inertia_dot[0], shape.inertia_dot[3], shape.inertia_dot[4]],
                [shape.inertia_dot[3], shape.inertia_dot[1], shape.inertia_dot[5]],
                [shape.inertia_dot[4], shape.inertia_dot[5], shape.inertia_dot[2]],
            ]
        ),
        atol=1e-6,
    )
    np.testing.assert_allclose(
        shape.inertia_matrix()
        @ np.array(
            [
                [shape.inertia_inv[0], shape.inertia_inv[3], shape.inertia_inv[4]],
                [shape.inertia_inv[3], shape.inertia_inv[1], shape.inertia_inv[5]],
                [shape.inertia_inv[4], shape.inertia_inv[5], shape.inertia_inv[2]],
            ]
        ),
        np.eye(3),
        atol=1e-9,
    )


def test_symmetric_shape_has_the_paper_inertia_and_radii() -> None:
    radii = (1.7, 0.31, 0.22)
    sim = Simulator(MODEL, SimConfig(), InitialState(position_m=(0, 0, 10), radii_m=radii))
    s = sim.state()
    np.testing.assert_allclose(s.principal_inertia_kg_m2, principal_inertia(MODEL, radii))
    np.testing.assert_allclose(
        s.inertia_tensor_kg_m2, np.diag(s.principal_inertia_kg_m2), atol=1e-12
    )
    np.testing.assert_allclose(
        s.radii_m, radii_from_joint_positions(MODEL, s.joint_position), rtol=1e-12
    )
    np.testing.assert_allclose(s.radii_m, radii, rtol=1e-12)


# --- contact ---------------------------------------------------------------------------
# Subnormal numbers are left out: they carry a few significant bits, so mu * fz rounds
# by more than the cone's relative margin (mu = 5e-324 failed by one subnormal step).
@settings(max_examples=500, deadline=None)
@given(
    st.floats(-0.1, 0.1, allow_subnormal=False),
    st.floats(-10.0, 10.0, allow_subnormal=False),
    st.floats(-10.0, 10.0, allow_subnormal=False),
    st.floats(-10.0, 10.0, allow_subnormal=False),
    st.floats(0.0, 2.0, allow_subnormal=False),
)
def test_contact_force_stays_inside_the_friction_cone(z, vx, vy, vz, mu) -> None:
    fx, fy, fz = ground_contact_force(z, vx, vy, vz, 5e4, 1e3, mu, 1e3)
    assert fz >= 0.0
    assert math.hypot(fx, fy) <= mu * fz * (1 + 1e-12)
    if z >= 0.0:
        assert (fx, fy, fz) == (0.0, 0.0, 0.0)
    if fz > 0.0 and math.hypot(vx, vy) > 0.0:  # friction opposes the slip
        assert fx * vx + fy * vy <= 0.0


def test_contact_is_a_spring_damper_in_penetration() -> None:
    assert ground_contact_force(-0.002, 0.0, 0.0, -0.1, 5e4, 1e3, 0.8, 1e3) == (
        0.0,
        0.0,
        pytest.approx(5e4 * 0.002 + 1e3 * 0.1),
    )
    # fast slip saturates on the cone; slow slip is viscous below it
    fx, _, fz = ground_contact_force(-0.002, 1.0, 0.0, 0.0, 5e4, 1e3, 0.8, 1e3)
    assert fx == pytest.approx(-0.8 * fz)
    fx, _, _ = ground_contact_force(-0.002, 0.01, 0.0, 0.0, 5e4, 1e3, 0.8, 1e3)
    assert fx == pytest.approx(-10.0)


# --- configuration and construction -------------------------------------------------------
@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("dt_s", 0.0),
        ("dt_s", math.nan),
        ("gravity_m_s2", -1.0),
        ("contact_stiffness_n_m", 0.0),
        ("friction_coefficient", -0.1),
        ("contact_substeps", 0),
        ("ground_contact", 1),
    ],
)
def test_sim_config_names_the_invalid_field(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=f"SimConfig.{field}"):
        SimConfig(**{field: value})


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("position_m", (0.0, math.inf, 0.0)),
        ("velocity_m_s", (1.0, 2.0)),
        ("orientation_wxyz", (1.0, 0.5, 0.0, 0.0)),
        ("radii_m", "abc"),
    ],
)
def test_initial_state_names_the_invalid_field(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=f"InitialState.{field}"):
        InitialState(**{field: value})


def test_unreachable_initial_radii_are_refused() -> None:
    with pytest.raises(ValueError, match="radii_m"):
        Simulator(MODEL, SimConfig(), InitialState(radii_m=(2.8, 0.6, 0.2)))


# --- the state snapshot ----------------------------------------------------------------
def test_a_snapshot_is_finite_unless_a_number_is_nan_or_infinite() -> None:
    state = Simulator(MODEL, SimConfig(), InitialState()).state()
    assert state.is_finite()
    huge = np.full(3, 1e308)  # finite, but their sum overflows
    assert replace(state, position_m=huge, velocity_m_s=huge).is_finite()
    for bad in (math.nan, math.inf, -math.inf):
        assert not replace(state, tether_tension_n=bad).is_finite()
        vector = np.array([0.0, bad, 1.0])
        assert not replace(state, angular_velocity_rad_s=vector).is_finite()
    opposite = replace(
        state, position_m=np.array([math.inf, 0, 0]), velocity_m_s=np.array([-math.inf, 0, 0])
    )
    assert not opposite.is_finite()  # (their sum is NaN)
