"""The shared robot model against the paper's closed forms (section III.B)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from splitter_model.joints import limb_joints
from splitter_model.kinematics import (
    joint_positions_from_radii,
    limb_forward_kinematics,
    limb_inverse_kinematics,
    limb_jacobian,
    limb_jacobians,
    limb_joint_torques,
    limb_offsets_from_joint_positions,
    radii_from_joint_positions,
)
from splitter_model.model import (
    PAPER_INITIAL_RADII_M,
    InfeasibleInertiaError,
    RobotModel,
    gravity_from_name,
    inertia_tensor,
    lumped_mass_positions,
    principal_inertia,
    radii_from_inertia,
    tether_tension,
    tether_tension_3d,
)

MODEL = RobotModel()


def test_paper_initial_inertia() -> None:
    # Ixx = 4*1.5*0.04*2, Iyy = Izz = 18*2.8^2 + 4*1.5*0.04
    np.testing.assert_allclose(
        principal_inertia(MODEL, PAPER_INITIAL_RADII_M), [0.48, 141.36, 141.36], rtol=1e-12
    )
    assert MODEL.total_mass_kg == pytest.approx(18.0)


def test_point_mass_tensor_matches_closed_form_and_is_diagonal() -> None:
    positions = lumped_mass_positions([1.3, 0.25, 0.15])
    tensor = inertia_tensor(MODEL.lumped_masses_kg, positions)
    np.testing.assert_allclose(np.diag(tensor), principal_inertia(MODEL, [1.3, 0.25, 0.15]))
    np.testing.assert_allclose(tensor - np.diag(np.diag(tensor)), 0.0, atol=1e-12)


def test_asymmetric_limbs_give_products_of_inertia() -> None:
    offsets = np.array([[0.0, 0.2, 0.0], [0.0, -0.2, 0.0], [0.0, 0.0, 0.2], [0.0, 0.0, -0.2]] * 2)
    offsets[0] = [0.1, 0.2, 0.0]  # one limb tip swung along x
    tensor = inertia_tensor(MODEL.lumped_masses_kg, lumped_mass_positions([2.8, 0.2, 0.2], offsets))
    assert abs(tensor[0, 1]) > 1e-3
    np.testing.assert_allclose(tensor, tensor.T)


@settings(max_examples=2000, deadline=None)
@given(
    st.floats(0.5, 3.0),
    st.floats(MODEL.limb_radius_min_m, MODEL.limb_radius_max_m),
    st.floats(MODEL.limb_radius_min_m, MODEL.limb_radius_max_m),
)
def test_radii_inertia_round_trip(rx: float, ry: float, rz: float) -> None:
    radii = np.array([rx, ry, rz])
    np.testing.assert_allclose(
        radii_from_inertia(MODEL, principal_inertia(MODEL, radii)), radii, rtol=1e-9, atol=1e-12
    )


def test_infeasible_inertia_raises_instead_of_nan() -> None:
    with pytest.raises(InfeasibleInertiaError):
        radii_from_inertia(MODEL, [10.0, 1.0, 1.0])  # Ixx > Iyy + Izz
    with pytest.raises(InfeasibleInertiaError):
        radii_from_inertia(MODEL, [np.nan, 1.0, 1.0])


def test_tension_reduces_to_paper_formula() -> None:
    assert tether_tension(MODEL, 1.0, 2.8) == pytest.approx(3.0 * 2.8)
    # the whole hemi (body + limbs, 9 kg) hangs on the tether
    assert tether_tension_3d(MODEL, [0.3, 1.0, 0.0], 2.8) == pytest.approx(9.0 * 2.8)


@settings(max_examples=2000, deadline=None)
@given(
    st.integers(0, 7),
    st.floats(-1.5, 1.5),
    st.floats(-3.0, 3.0),
    st.floats(MODEL.knee_min_rad, MODEL.knee_max_rad),
)
def test_limb_ik_fk_round_trip(limb: int, q1: float, q2: float, q3: float) -> None:
    tip = limb_forward_kinematics(MODEL, limb, [q1, q2, q3])
    q = limb_inverse_kinematics(MODEL, limb, tip)
    np.testing.assert_allclose(limb_forward_kinematics(MODEL, limb, q), tip, atol=1e-9)


def test_radial_joint_positions_reproduce_radii_and_lumped_positions() -> None:
    radii = np.array([2.1, 0.33, 0.15])
    q = joint_positions_from_radii(MODEL, radii)
    np.testing.assert_allclose(radii_from_joint_positions(MODEL, q), radii, atol=1e-12)
    offsets = limb_offsets_from_joint_positions(MODEL, q)
    np.testing.assert_allclose(
        lumped_mass_positions(radii, offsets), lumped_mass_positions(radii), atol=1e-12
    )


@settings(max_examples=40, deadline=None)
@given(
    limb=st.integers(0, 7),
    q1=st.floats(-1.4, 1.4),
    q2=st.floats(-1.2, 1.2),
    q3=st.floats(0.2, 2.5),
)
def test_limb_jacobian_is_the_derivative_of_the_forward_kinematics(
    limb: int, q1: float, q2: float, q3: float
) -> None:
    q, step = np.array([q1, q2, q3]), 1e-6
    numeric = np.stack(
        [
            (
                limb_forward_kinematics(MODEL, limb, q + step * e)
                - limb_forward_kinematics(MODEL, limb, q - step * e)
            )
            / (2.0 * step)
            for e in np.eye(3)
        ],
        axis=1,
    )
    np.testing.assert_allclose(limb_jacobian(MODEL, limb, q), numeric, atol=1e-8)


def test_all_limb_jacobians_at_once_equal_each_limbs() -> None:
    """The vectorised form (the simulator's snapshot) is the per-limb closed form."""
    rng = np.random.default_rng(7)
    q = rng.uniform(-2.5, 2.5, 25)
    at_once = limb_jacobians(MODEL, q)
    forces = rng.normal(0.0, 5.0, (8, 3))
    torques = limb_joint_torques(MODEL, q, forces)
    for limb in range(8):
        jacobian = limb_jacobian(MODEL, limb, q[limb_joints(limb)])
        np.testing.assert_array_equal(at_once[limb], jacobian)
        # bit for bit each limb's J^T F: the flight estimator reads these efforts
        np.testing.assert_array_equal(torques[limb_joints(limb)], jacobian.T @ forces[limb])


def test_joint_torques_do_the_work_of_the_tip_force() -> None:
    """Virtual work: tau . qd = F . v for any joint rates (massless links)."""
    rng = np.random.default_rng(3)
    q = joint_positions_from_radii(MODEL, (2.0, 0.3, 0.2)) + rng.normal(0.0, 0.1, 25)
    forces = rng.normal(0.0, 2.0, (8, 3))
    qd = rng.normal(0.0, 1.0, 25)
    torques = limb_joint_torques(MODEL, q, forces)
    tip_power = sum(
        forces[limb] @ limb_jacobian(MODEL, limb, q[limb_joints(limb)]) @ qd[limb_joints(limb)]
        for limb in range(8)
    )
    assert float(torques @ qd[:24]) == pytest.approx(tip_power, rel=1e-12)


def test_unreachable_tip_is_an_error() -> None:
    with pytest.raises(ValueError, match="outside"):
        limb_inverse_kinematics(MODEL, 0, [0.0, 0.5, 0.0])


def test_gravity_presets_and_errors() -> None:
    assert gravity_from_name("moon") == pytest.approx(9.80665 / 6)
    assert gravity_from_name(1.0) == 1.0
    with pytest.raises(ValueError, match="unknown gravity"):
        gravity_from_name("jupiter-ish")
    with pytest.raises(ValueError):
        RobotModel(body_mass_kg=-1.0)
