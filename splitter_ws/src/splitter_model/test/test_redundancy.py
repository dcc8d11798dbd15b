"""What remains after a fault (:mod:`splitter_model.redundancy`), against the ten-mass model."""

from __future__ import annotations

import numpy as np
import pytest

from splitter_model.joints import JOINT_INDEX, LIMB_NAMES, TETHER_INDEX, limb_joints
from splitter_model.kinematics import joint_positions_from_radii, limb_offsets_from_joint_positions
from splitter_model.model import RobotModel, inertia_tensor, lumped_mass_positions
from splitter_model.reachable import reachable_set
from splitter_model.redundancy import (
    LimbRoles,
    fold_stop_pitch_rad,
    held_limb_command,
    limb_reaches_m,
    mirror_limb,
    mirror_limb_command,
    remaining_shape,
)

MODEL = RobotModel()


def _tensor(q: np.ndarray) -> np.ndarray:
    offsets = limb_offsets_from_joint_positions(MODEL, q)
    positions = lumped_mass_positions((q[TETHER_INDEX] / 2.0, 0.2, 0.2), offsets)
    return inertia_tensor(MODEL.lumped_masses_kg, positions)


def test_each_limb_mirrors_the_other_of_its_hemi_along_its_axis() -> None:
    pairs = {LIMB_NAMES[i]: LIMB_NAMES[mirror_limb(i)] for i in range(8)}
    assert pairs["hemi_a_y_pos"] == "hemi_a_y_neg"
    assert pairs["hemi_b_z_neg"] == "hemi_b_z_pos"
    assert all(mirror_limb(mirror_limb(i)) == i for i in range(8))


def test_roles_of_a_failed_knee_and_reel() -> None:
    roles = LimbRoles.from_failed_joints([JOINT_INDEX["hemi_a_y_pos_knee"], TETHER_INDEX])
    assert roles.held == {0} and roles.mirrors == ((1, 0),) and roles.reel_locked
    assert roles.free_limbs(1) == (4, 5) and roles.free_limbs(2) == (2, 3, 6, 7)
    both = LimbRoles.from_failed_joints(
        [JOINT_INDEX["hemi_a_y_pos_knee"], JOINT_INDEX["hemi_a_y_neg_hip_pitch"]]
    )
    assert both.held == {0, 1} and both.mirrors == ()
    abduction = LimbRoles.from_failed_joints([JOINT_INDEX["hemi_b_z_pos_hip_abduction"]])
    assert abduction.healthy  # the tip stays on that joint's axis: nothing to hold


def test_a_mirror_cancels_the_products_of_inertia_of_a_held_limb() -> None:
    q = joint_positions_from_radii(MODEL, (2.8, 0.2, 0.2))
    held = limb_joints(0)
    q[held] = (0.3, -0.4, 1.2)  # a limb swung off its axis
    alone = _tensor(q)
    q[limb_joints(mirror_limb(0))] = q[held]
    mirrored = _tensor(q)
    assert abs(alone[0, 1]) > 0.3  # [kg m^2] the swing tilts the principal axes
    assert abs(mirrored[0, 1]) < 1e-12 and abs(mirrored[0, 2]) < 1e-12


def test_the_remaining_set_is_the_mean_of_squared_reaches() -> None:
    q = joint_positions_from_radii(MODEL, (2.8, 0.35, 0.2))
    knee = JOINT_INDEX["hemi_a_y_pos_knee"]
    shape = remaining_shape(MODEL, [knee], q)
    remaining = shape.reachable(MODEL)
    nominal = reachable_set(MODEL)
    r_min, r_max = MODEL.limb_radius_min_m, MODEL.limb_radius_max_m
    # two y limbs (held and mirror) at 0.35 m, two free over the knee range
    assert remaining.radius_min_m[1] == pytest.approx(np.sqrt((2 * 0.35**2 + 2 * r_min**2) / 4))
    assert remaining.radius_max_m[1] == pytest.approx(np.sqrt((2 * 0.35**2 + 2 * r_max**2) / 4))
    assert np.array_equal(remaining.radius_min_m[[0, 2]], nominal.radius_min_m[[0, 2]])
    # the free limbs' reach for an effective radius, and back
    free = shape.free_radius_m(1, 0.3**2)
    assert shape.radius_squared(1, free) == pytest.approx(0.3**2)
    assert limb_reaches_m(MODEL, q)[0] == pytest.approx(0.35)


def test_a_locked_reel_leaves_r_x_where_it_stopped() -> None:
    q = joint_positions_from_radii(MODEL, (2.1, 0.2, 0.2))
    remaining = remaining_shape(MODEL, [TETHER_INDEX], q).reachable(MODEL)
    assert remaining.radius_min_m[0] == pytest.approx(2.1, abs=1.01e-3)
    assert remaining.radius_max_m[0] == pytest.approx(2.1, abs=1.01e-3)
    assert remaining.radius_min_m[0] < remaining.radius_max_m[0]


def test_a_held_limb_folds_away_from_a_limp_joint_only() -> None:
    measured = np.array([0.0, -0.9, 1.8])
    knee, pitch = JOINT_INDEX["hemi_a_y_pos_knee"], JOINT_INDEX["hemi_a_y_pos_hip_pitch"]
    assert np.array_equal(held_limb_command(MODEL, 0, measured, []), measured)  # locked: held
    limp_knee = held_limb_command(MODEL, 0, measured, [knee])
    assert limp_knee[1] == fold_stop_pitch_rad(MODEL) and limp_knee[2] == measured[2]
    # the shank's equilibrium along the tether (pitch + knee = pi/2) is past the fold stop
    assert np.pi / 2 - fold_stop_pitch_rad(MODEL) > MODEL.knee_max_rad
    limp_pitch = held_limb_command(MODEL, 0, measured, [pitch])
    assert limp_pitch[2] == MODEL.knee_max_rad and limp_pitch[1] == measured[1]


def test_a_mirror_copies_its_held_limb_except_a_z_limbs_limp_hip_pitch_swing() -> None:
    held = np.array([0.1, 0.7, MODEL.knee_max_rad])  # where a limp hip pitch swung, folded
    previous = np.array([0.0, -1.05, 2.09])  # the mirror's last command
    z_limb = LIMB_NAMES.index("hemi_a_z_pos")
    z_knee, z_pitch = JOINT_INDEX["hemi_a_z_pos_knee"], JOINT_INDEX["hemi_a_z_pos_hip_pitch"]
    for moving in ([], [z_knee], [JOINT_INDEX["hemi_a_z_neg_hip_pitch"]]):
        assert np.array_equal(mirror_limb_command(z_limb, held, previous, moving), held)
    mirrored = mirror_limb_command(z_limb, held, previous, [z_pitch])
    assert mirrored[1] == previous[1]  # its hip pitch stays where it was
    assert mirrored[0] == held[0] and mirrored[2] == held[2]  # the same reach: folded
    assert limb_reaches_m(MODEL, _limb_pose(z_limb, held))[z_limb] == pytest.approx(
        limb_reaches_m(MODEL, _limb_pose(z_limb, mirrored))[z_limb], abs=1e-12
    )
    # a y limb's swing tilts the spin axis (I_xy): its mirror copies it to cancel that
    y_pitch = JOINT_INDEX["hemi_a_y_pos_hip_pitch"]
    assert np.array_equal(mirror_limb_command(0, held, previous, [y_pitch]), held)


def test_a_z_limbs_swing_leaves_y_principal_a_y_limbs_tilts_it() -> None:
    """Why only a z limb's mirror may hold: the products of inertia of a lone swing."""
    q = joint_positions_from_radii(MODEL, (2.8, 0.2, 0.2))
    for limb, coupled in ((LIMB_NAMES.index("hemi_a_z_pos"), (0, 2)), (0, (0, 1))):
        swung = q.copy()
        swung[limb_joints(limb).start + 1] += 0.5  # [rad] the hip pitch swung
        tensor = _tensor(swung)
        off = [(i, j) for i in range(3) for j in range(i + 1, 3) if abs(tensor[i, j]) > 1e-9]
        assert off == [coupled]


def _limb_pose(limb: int, angles: np.ndarray) -> np.ndarray:
    q = joint_positions_from_radii(MODEL, (2.0, 0.2, 0.2))
    q[limb_joints(limb)] = angles
    return q
