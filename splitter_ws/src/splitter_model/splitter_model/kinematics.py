"""Limb and tether kinematics of SPLITTER: joint angles <-> limb-tip (mass) positions.

Each of the eight limbs has hip abduction, hip pitch and knee joints (thigh and
shank of ``RobotModel.thigh_length_m`` / ``shank_length_m``); the tether is a
prismatic joint whose position is the distance between the two hemi bodies
(2 r_x). ROS-free; shared by the simulator (commands -> mass positions) and the
IK / tether allocator (radii -> joint angles).

Limb frame: ``u`` is the outward axis the limb reaches along (+-y or +-z of the
body frame), ``v`` points along the tether away from the centre (s x), and
``w = u x v``. Hip pitch and knee bend the limb in the plane spanned by ``u`` and
the abduction-rotated ``v``; hip abduction rotates that plane about ``u``. With
zero abduction and ``hip_pitch = -atan2(L2 sin(knee), L1 + L2 cos(knee))`` the tip
lies on ``u`` at distance ``limb_reach_m(knee)``: the paper's radius r_y or r_z.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.joints import (
    LIMB_AXES,
    LIMB_AXIS_OF,
    LIMB_HEMI_SIGNS,
    LIMB_RADIUS_INDEX,
    N_JOINTS,
    N_LIMBS,
    TETHER_INDEX,
    limb_joints,
    limbs_along,
)
from splitter_model.model import RobotModel

_E = np.eye(3)
# Outward axis u of each limb, in the order of splitter_model.joints.LIMB_AXES.
LIMB_OUTWARD_AXES = (_E[1], -_E[1], _E[2], -_E[2])
_Y_LIMBS, _Z_LIMBS = list(limbs_along("y")), list(limbs_along("z"))


def _limb_frame_rows(limb_index: int) -> NDArray[np.float64]:
    u = LIMB_OUTWARD_AXES[LIMB_AXES.index(LIMB_AXIS_OF[limb_index])]
    v = LIMB_HEMI_SIGNS[limb_index] * _E[0]
    return np.stack([u, v, np.cross(u, v)])


# (8, 3, 3): rows (u, v, w) of every limb, built once (constant geometry)
LIMB_FRAMES = np.stack([_limb_frame_rows(limb) for limb in range(N_LIMBS)])
LIMB_FRAMES.setflags(write=False)


def limb_frame(limb_index: int) -> NDArray[np.float64]:
    """Rows (u, v, w) of limb ``limb_index`` (0..7, order of ``joints.LIMB_NAMES``)."""
    return LIMB_FRAMES[limb_index].copy()


@dataclass(frozen=True)
class _LimbPlane:
    """A limb's pose in its bending plane: tip along ``u`` and along the rotated ``v``."""

    p_u: float  # [m] tip along u
    p_plane: float  # [m] tip along v_rot
    u: NDArray[np.float64]
    v_rot: NDArray[np.float64]  # v turned about u by the hip abduction
    d_v_rot: NDArray[np.float64]  # d(v_rot)/d(hip abduction)
    knee_u: float  # [m] the shank's part of p_u
    knee_plane: float  # [m] the shank's part of p_plane


def _limb_plane(model: RobotModel, limb_index: int, joint_angles_rad: ArrayLike) -> _LimbPlane:
    q1, q2, q3 = (float(a) for a in np.asarray(joint_angles_rad, dtype=float))
    l1, l2 = model.thigh_length_m, model.shank_length_m
    knee_u, knee_plane = l2 * math.cos(q2 + q3), l2 * math.sin(q2 + q3)
    u, v, w = LIMB_FRAMES[limb_index]
    return _LimbPlane(
        p_u=l1 * math.cos(q2) + knee_u,
        p_plane=l1 * math.sin(q2) + knee_plane,
        u=u,
        v_rot=math.cos(q1) * v + math.sin(q1) * w,
        d_v_rot=-math.sin(q1) * v + math.cos(q1) * w,
        knee_u=knee_u,
        knee_plane=knee_plane,
    )


def limb_forward_kinematics(
    model: RobotModel, limb_index: int, joint_angles_rad: ArrayLike
) -> NDArray[np.float64]:
    """Tip position [m] relative to the hip (the hemi body) in the base frame.

    ``joint_angles_rad`` is (hip_abduction, hip_pitch, knee).
    """
    plane = _limb_plane(model, limb_index, joint_angles_rad)
    return plane.p_u * plane.u + plane.p_plane * plane.v_rot


def limb_jacobian(
    model: RobotModel, limb_index: int, joint_angles_rad: ArrayLike
) -> NDArray[np.float64]:
    """d(tip position)/d(hip_abduction, hip_pitch, knee) [m/rad], base frame, columns (3, 3).

    The analytic derivative of :func:`limb_forward_kinematics`: the tip's velocity
    is ``J qd`` and, the links being massless, the joint torques that hold a force
    ``F`` [N] on the tip's lumped mass are ``J^T F`` [N m] (virtual work).
    """
    p = _limb_plane(model, limb_index, joint_angles_rad)
    d_knee = -p.knee_plane * p.u + p.knee_u * p.v_rot
    d_pitch = -p.p_plane * p.u + p.p_u * p.v_rot
    return np.stack([p.p_plane * p.d_v_rot, d_pitch, d_knee], axis=1)


def limb_jacobians(model: RobotModel, joint_positions: ArrayLike) -> NDArray[np.float64]:
    """(8, 3, 3): :func:`limb_jacobian` of every limb at once [m/rad].

    ``joint_positions``: the joints in ``JOINT_NAMES`` order (the tether's entry, if
    given, is not read). The same closed form, vectorised over the limbs: the
    simulator's snapshot takes it at every step.
    """
    q = np.asarray(joint_positions, dtype=float)[: 3 * N_LIMBS].reshape(N_LIMBS, 3)
    q1, q2, q23 = q[:, 0], q[:, 1], q[:, 1] + q[:, 2]
    l1, l2 = model.thigh_length_m, model.shank_length_m
    knee_u, knee_plane = l2 * np.cos(q23), l2 * np.sin(q23)
    p_u = l1 * np.cos(q2) + knee_u
    p_plane = l1 * np.sin(q2) + knee_plane
    u, v, w = LIMB_FRAMES[:, 0], LIMB_FRAMES[:, 1], LIMB_FRAMES[:, 2]
    c1, s1 = np.cos(q1)[:, None], np.sin(q1)[:, None]
    v_rot = c1 * v + s1 * w
    d_v_rot = -s1 * v + c1 * w
    d_knee = -knee_plane[:, None] * u + knee_u[:, None] * v_rot
    d_pitch = -p_plane[:, None] * u + p_u[:, None] * v_rot
    return np.stack([p_plane[:, None] * d_v_rot, d_pitch, d_knee], axis=2)


def limb_joint_torques(
    model: RobotModel, joint_positions: ArrayLike, tip_forces_n: ArrayLike
) -> NDArray[np.float64]:
    """The 24 limb joint torques [N m] (``JOINT_NAMES`` order) holding ``tip_forces_n``.

    ``tip_forces_n``: (8, 3) the force each limb exerts on its lumped mass, base frame [N].
    """
    forces = np.asarray(tip_forces_n, dtype=float).reshape(N_LIMBS, 3)
    # J^T F per limb as a batched matmul: the same sums, in the same order, as each
    # limb's J.T @ F (einsum sums otherwise: last-bit differences in the efforts the
    # flight estimator reads)
    jacobians_t = limb_jacobians(model, joint_positions).transpose(0, 2, 1)
    return np.matmul(jacobians_t, forces[:, :, None]).ravel()


def limb_inverse_kinematics(
    model: RobotModel, limb_index: int, tip_position_m: ArrayLike
) -> NDArray[np.float64]:
    """(hip_abduction, hip_pitch, knee) [rad] placing the tip at ``tip_position_m``.

    ``tip_position_m`` is relative to the hip, base frame. Knee-positive branch,
    abduction within +-pi/2. Raises ``ValueError`` when the tip is out of the
    knee's reach (use :func:`limb_reach_limits`).
    """
    p = np.asarray(tip_position_m, dtype=float)
    u, v, w = limb_frame(limb_index)
    p_u, p_v, p_w = float(p @ u), float(p @ v), float(p @ w)
    rho = math.hypot(p_v, p_w)
    if rho < 1e-12:
        q1 = 0.0
    else:
        q1 = math.atan2(p_w, p_v)
        if q1 > math.pi / 2:
            q1, rho = q1 - math.pi, -rho
        elif q1 <= -math.pi / 2:
            q1, rho = q1 + math.pi, -rho
    l1, l2 = model.thigh_length_m, model.shank_length_m
    d = math.hypot(p_u, rho)
    d_min, d_max = limb_reach_limits(model)
    if not d_min - 1e-12 <= d <= d_max + 1e-12:
        raise ValueError(f"limb tip at distance {d:.4f} m is outside [{d_min:.4f}, {d_max:.4f}] m")
    cos_knee = (d * d - l1 * l1 - l2 * l2) / (2.0 * l1 * l2)
    q3 = math.acos(min(1.0, max(-1.0, cos_knee)))
    q2 = math.atan2(rho, p_u) - math.atan2(l2 * math.sin(q3), l1 + l2 * math.cos(q3))
    return np.array([q1, q2, q3])


def limb_reach_limits(model: RobotModel) -> tuple[float, float]:
    """(min, max) hip-to-tip distance allowed by the knee range [m]."""
    return model.limb_radius_min_m, model.limb_radius_max_m


def radial_limb_joint_angles(model: RobotModel, radius_m: float) -> NDArray[np.float64]:
    """Joint angles placing the tip on the limb's outward axis at ``radius_m`` [rad]."""
    l1, l2 = model.thigh_length_m, model.shank_length_m
    cos_knee = (radius_m * radius_m - l1 * l1 - l2 * l2) / (2.0 * l1 * l2)
    q3 = math.acos(min(1.0, max(-1.0, cos_knee)))
    q2 = -math.atan2(l2 * math.sin(q3), l1 + l2 * math.cos(q3))
    return np.array([0.0, q2, q3])


def joint_positions_from_radii(model: RobotModel, radii_m: ArrayLike) -> NDArray[np.float64]:
    """All 25 joint positions (order of ``joints.JOINT_NAMES``) for symmetric radii.

    Limb joints [rad] for r_y (y limbs) and r_z (z limbs); tether [m] = 2 r_x.
    """
    radii = [float(v) for v in np.asarray(radii_m, dtype=float)]
    q = np.zeros(N_JOINTS)
    for limb in range(N_LIMBS):
        q[limb_joints(limb)] = radial_limb_joint_angles(model, radii[LIMB_RADIUS_INDEX[limb]])
    q[TETHER_INDEX] = 2.0 * radii[0]
    return q


def limb_offsets_from_joint_positions(
    model: RobotModel, joint_positions: ArrayLike
) -> NDArray[np.float64]:
    """Tip offsets (8, 3) [m] from each hemi body, from the 24 limb joint angles."""
    q = np.asarray(joint_positions, dtype=float)
    return np.stack(
        [limb_forward_kinematics(model, limb, q[limb_joints(limb)]) for limb in range(N_LIMBS)]
    )


def radii_from_joint_positions(
    model: RobotModel, joint_positions: ArrayLike
) -> NDArray[np.float64]:
    """Effective (r_x, r_y, r_z) [m]: half the tether, mean y-limb and z-limb reach."""
    q = np.asarray(joint_positions, dtype=float)
    offsets = limb_offsets_from_joint_positions(model, q)
    reach = np.linalg.norm(offsets, axis=1)
    ry = float(np.mean(reach[_Y_LIMBS]))
    rz = float(np.mean(reach[_Z_LIMBS]))
    return np.array([q[TETHER_INDEX] / 2.0, ry, rz])
