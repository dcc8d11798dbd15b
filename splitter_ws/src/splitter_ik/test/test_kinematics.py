"""Limb IK/FK round trips and the radial knee Jacobian."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from splitter_ik.core.radial_kinematics import (
    hip_pitch_rate_per_knee_rate,
    hip_pitch_speed_ratio_max,
    joint_velocities_from_radii_rate,
    knee_from_radius,
    radial_hip_pitch,
    radius_from_knee,
)
from splitter_model.kinematics import (
    joint_positions_from_radii,
    limb_forward_kinematics,
    limb_inverse_kinematics,
    limb_offsets_from_joint_positions,
    radial_limb_joint_angles,
    radii_from_joint_positions,
)
from splitter_model.model import RobotModel
from splitter_msgs_py import names

MODEL = RobotModel()
R_MIN, R_MAX = MODEL.radii_min_m, MODEL.radii_max_m
TOL = 1e-9

limb_angles = st.tuples(
    st.integers(0, 7),
    st.floats(-math.pi / 2 + 1e-6, math.pi / 2 - 1e-6),
    st.floats(-math.pi + 1e-6, math.pi - 1e-6),
    st.floats(MODEL.knee_min_rad, MODEL.knee_max_rad),
)


def _check_fk_ik_fk(limb: int, q1: float, q2: float, q3: float) -> None:
    tip = limb_forward_kinematics(MODEL, limb, [q1, q2, q3])
    q = limb_inverse_kinematics(MODEL, limb, tip)
    np.testing.assert_allclose(limb_forward_kinematics(MODEL, limb, q), tip, rtol=0.0, atol=TOL)
    # the knee is unique (positive branch); the reach is what the knee sets
    assert q[2] == pytest.approx(q3, abs=1e-7)
    assert float(np.linalg.norm(tip)) == pytest.approx(MODEL.limb_reach_m(q3), abs=TOL)


def test_limb_fk_ik_fk_round_trip_over_8000_configurations() -> None:
    rng = np.random.default_rng(5)
    for limb in range(8):
        for q1, q2, q3 in rng.uniform(
            [-math.pi / 2 + 1e-6, -math.pi + 1e-6, MODEL.knee_min_rad],
            [math.pi / 2 - 1e-6, math.pi - 1e-6, MODEL.knee_max_rad],
            size=(1000, 3),
        ):
            _check_fk_ik_fk(limb, q1, q2, q3)


@settings(max_examples=300, deadline=None)
@given(limb_angles)
def test_limb_fk_ik_fk_round_trip_property(sample: tuple[int, float, float, float]) -> None:
    _check_fk_ik_fk(*sample)


@settings(max_examples=1000, deadline=None)
@given(
    st.integers(0, 7),
    st.floats(-1.0, 1.0),
    st.floats(-1.0, 1.0),
    st.floats(-1.0, 1.0),
    st.floats(0.0, 1.0),
)
def test_limb_ik_fk_round_trip_from_tip_positions(
    limb: int, x: float, y: float, z: float, fraction: float
) -> None:
    direction = np.array([x, y, z])
    if np.linalg.norm(direction) < 1e-3:
        direction = np.array([0.0, 1.0, 0.0])
    radius = R_MIN[1] + fraction * (R_MAX[1] - R_MIN[1])
    tip = radius * direction / np.linalg.norm(direction)
    q = limb_inverse_kinematics(MODEL, limb, tip)
    assert MODEL.knee_min_rad - 1e-12 <= q[2] <= MODEL.knee_max_rad + 1e-12
    assert abs(q[0]) <= math.pi / 2 + 1e-12
    np.testing.assert_allclose(limb_forward_kinematics(MODEL, limb, q), tip, rtol=0.0, atol=TOL)


def _check_radii_joints_radii(rx: float, ry: float, rz: float) -> None:
    q = joint_positions_from_radii(MODEL, [rx, ry, rz])
    assert q.shape == (names.N_JOINTS,)
    assert q[names.JOINT_INDEX[names.TETHER_JOINT]] == pytest.approx(2.0 * rx, abs=1e-15)
    np.testing.assert_allclose(radii_from_joint_positions(MODEL, q), [rx, ry, rz], atol=TOL)
    assert radius_from_knee(MODEL, knee_from_radius(MODEL, ry)) == pytest.approx(ry, abs=TOL)
    # every limb tip lies on its outward axis
    tips = limb_offsets_from_joint_positions(MODEL, q)
    radius = np.array([ry, ry, rz, rz] * 2)[:, None]
    np.testing.assert_allclose(tips, radius * OUTWARD, atol=TOL)


OUTWARD = np.array([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]] * 2)


def test_radii_joint_positions_radii_round_trip_over_3000_configurations() -> None:
    for r in np.random.default_rng(9).uniform(R_MIN, R_MAX, size=(3000, 3)):
        _check_radii_joints_radii(*r)


@settings(max_examples=300, deadline=None)
@given(
    st.floats(float(R_MIN[0]), float(R_MAX[0])),
    st.floats(float(R_MIN[1]), float(R_MAX[1])),
    st.floats(float(R_MIN[2]), float(R_MAX[2])),
)
def test_radii_joint_positions_radii_round_trip_property(rx: float, ry: float, rz: float) -> None:
    _check_radii_joints_radii(rx, ry, rz)


@settings(max_examples=200, deadline=None)
@given(st.floats(MODEL.knee_min_rad, MODEL.knee_max_rad))
def test_radial_hip_pitch_matches_shared_kinematics(knee: float) -> None:
    expected = radial_limb_joint_angles(MODEL, MODEL.limb_reach_m(knee))
    assert radial_hip_pitch(MODEL, knee) == pytest.approx(expected[1], abs=1e-9)
    # equal thigh and shank: the hip turns exactly half the knee
    assert radial_hip_pitch(MODEL, knee) == pytest.approx(-knee / 2.0, abs=1e-12)
    assert hip_pitch_rate_per_knee_rate(MODEL, knee) == pytest.approx(-0.5, abs=1e-12)


def test_hip_speed_ratio_for_unequal_links_is_found_at_the_range_ends() -> None:
    model = RobotModel(thigh_length_m=0.15, shank_length_m=0.25)
    grid = np.linspace(model.knee_min_rad, model.knee_max_rad, 20001)
    sampled = max(abs(hip_pitch_rate_per_knee_rate(model, k)) for k in grid)
    assert hip_pitch_speed_ratio_max(model) == pytest.approx(sampled, rel=1e-9)
    assert hip_pitch_speed_ratio_max(model) > 1.0  # the hip is the faster joint here


@settings(max_examples=300, deadline=None)
@given(
    st.floats(float(R_MIN[0]) + 0.01, float(R_MAX[0]) - 0.01),
    st.floats(float(R_MIN[1]) + 0.01, float(R_MAX[1]) - 0.01),
    st.floats(float(R_MIN[2]) + 0.01, float(R_MAX[2]) - 0.01),
    st.tuples(*[st.floats(-1.0, 1.0)] * 3),
)
def test_knee_jacobian_matches_finite_differences(
    rx: float, ry: float, rz: float, rate: tuple[float, float, float]
) -> None:
    radii, rdot = np.array([rx, ry, rz]), np.array(rate)
    h = 1e-6
    numeric = (
        joint_positions_from_radii(MODEL, radii + h * rdot)
        - joint_positions_from_radii(MODEL, radii - h * rdot)
    ) / (2.0 * h)
    analytic = joint_velocities_from_radii_rate(MODEL, radii, rdot)
    np.testing.assert_allclose(analytic, numeric, rtol=1e-5, atol=1e-5)


def test_knee_from_radius_rejects_out_of_reach() -> None:
    with pytest.raises(ValueError):
        knee_from_radius(MODEL, float(R_MAX[1]) + 1e-6)
    with pytest.raises(ValueError):
        knee_from_radius(MODEL, float("nan"))
