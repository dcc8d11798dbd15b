"""The allocator after a fault (``set_remaining``): held limbs, mirrors, free limbs, the reel."""

from __future__ import annotations

import numpy as np
import pytest

from splitter_ik.core.allocator import TetherLimbAllocator
from splitter_model.joints import JOINT_INDEX, TETHER_INDEX, limb_joints
from splitter_model.kinematics import limb_offsets_from_joint_positions
from splitter_model.model import (
    RobotModel,
    inertia_tensor,
    lumped_mass_positions,
    principal_inertia,
)
from splitter_model.redundancy import mirror_limb, remaining_shape

MODEL = RobotModel()
TICK_NS = 10_000_000
W = np.array([0.0, 1.0, 0.0])  # [rad/s]


def _diagonal(q: np.ndarray) -> np.ndarray:
    offsets = limb_offsets_from_joint_positions(MODEL, q)
    positions = lumped_mass_positions((q[TETHER_INDEX] / 2.0, 0.2, 0.2), offsets)
    return np.diag(inertia_tensor(MODEL.lumped_masses_kg, positions))


def _settle(allocator: TetherLimbAllocator, setpoint, start_tick: int, ticks: int, failed):
    allocation = None
    for k in range(start_tick, start_tick + ticks):
        q = allocator._state.joint_position  # the joints follow the plan exactly
        allocator.set_remaining(remaining_shape(MODEL, failed, q), q)
        allocation = allocator.allocate(k * TICK_NS, setpoint, W)
    return allocation


def test_a_held_limb_stays_its_mirror_copies_and_the_free_limbs_carry_the_radius() -> None:
    allocator = TetherLimbAllocator(MODEL, initial_radii_m=(2.5, 0.3, 0.2))
    knee = JOINT_INDEX["hemi_a_y_pos_knee"]
    held = allocator._state.joint_position[limb_joints(0)].copy()
    wanted = principal_inertia(MODEL, (2.5, 0.25, 0.25))  # free y limbs at 0.187 m
    a = _settle(allocator, wanted, 1, 300, [knee])
    q = np.asarray(a.joint_position)
    assert np.array_equal(q[limb_joints(0)], held)  # locked: held where it was
    assert np.array_equal(q[limb_joints(mirror_limb(0))], held)
    free = [q[limb_joints(limb)] for limb in (4, 5)]  # hemi b's y limbs
    assert np.array_equal(free[0], free[1])
    # the robot's moments (ten masses, held limbs where they are) are the setpoint's
    assert _diagonal(q) == pytest.approx(wanted, rel=1e-6)
    assert a.achieved_inertia_kg_m2 == pytest.approx(wanted, rel=1e-6)
    assert not a.saturated


def test_a_setpoint_beyond_what_remains_is_projected_onto_it() -> None:
    allocator = TetherLimbAllocator(MODEL, initial_radii_m=(2.5, 0.3, 0.2))
    knee = JOINT_INDEX["hemi_a_y_pos_knee"]
    wanted = principal_inertia(MODEL, (2.5, MODEL.limb_radius_min_m, 0.2))  # all y limbs folded
    a = _settle(allocator, wanted, 1, 300, [knee])
    assert a.saturated
    reach_y = np.sqrt((2 * 0.3**2 + 2 * MODEL.limb_radius_min_m**2) / 4)
    assert a.radii_m[1] == pytest.approx(reach_y, rel=1e-9)


def test_a_locked_reel_holds_the_tether_whatever_the_setpoint() -> None:
    allocator = TetherLimbAllocator(MODEL, initial_radii_m=(2.0, 0.2, 0.2))
    wanted = principal_inertia(MODEL, (3.0, 0.2, 0.2))
    a = _settle(allocator, wanted, 1, 100, [TETHER_INDEX])
    assert a.joint_position[TETHER_INDEX] == 4.0
    assert a.joint_velocity[TETHER_INDEX] == 0.0
    assert a.saturated


def test_the_mirror_of_a_z_limbs_limp_hip_pitch_holds_its_pitch_while_the_limb_swings() -> None:
    """A limp hip pitch swings (a pendulum in the centrifugal pull): its limb folds, the
    mirror of a z limb folds too but keeps its hip pitch instead of chasing the swing."""
    allocator = TetherLimbAllocator(MODEL, initial_radii_m=(2.5, 0.3, 0.2))
    pitch = JOINT_INDEX["hemi_a_z_pos_hip_pitch"]
    limb = pitch // 3
    mirror = limb_joints(mirror_limb(limb))
    mirror_pitch = float(allocator._state.joint_position[mirror.start + 1])
    wanted = principal_inertia(MODEL, (2.5, 0.25, 0.25))
    for k in range(1, 301):
        q = allocator._state.joint_position.copy()
        q[pitch] = 0.35 + 0.5 * np.sin(2.0 * np.pi * k * TICK_NS * 1e-9)  # the swing [rad]
        allocator.set_remaining(remaining_shape(MODEL, [pitch], q, moving_faults=[pitch]), q)
        a = allocator.allocate(k * TICK_NS, wanted, W)
        command = np.asarray(a.joint_position)
        assert command[mirror.start + 1] == pytest.approx(mirror_pitch, abs=1e-12)
    assert command[limb_joints(limb).stop - 1] == pytest.approx(MODEL.knee_max_rad)  # folded
    assert command[mirror.stop - 1] == pytest.approx(MODEL.knee_max_rad)
