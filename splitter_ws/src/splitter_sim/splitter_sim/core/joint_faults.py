"""The motion of limp joints: zero joint torque in the morphing body (``splitter_model.faults``).

A limb's links are massless and carry its lumped mass ``m_i`` at the tip, so the
torque of limb joint ``j`` is ``tau_j = J_j . F_i`` (virtual work; ``J_j`` the
column of :func:`~splitter_model.kinematics.limb_jacobian`, body frame) with
``F_i`` the force the limb exerts on the mass. In flight the centre of mass
falls freely, so ``F_i = m_i a_i`` with ``a_i`` the mass's inertial acceleration
relative to the COM, in body coordinates::

    a_i = ddr_i + 2 w x dr_i + dw/dt x r_i + w x (w x r_i)
    w = I^-1 (L - h),   dw/dt = I^-1 (dL/dt - dh/dt - dI/dt w),   dL/dt = -w x L

(``r_i`` relative to the COM, ``h = sum m r x dr``, ``L`` the body-frame momentum,
:mod:`.rigid_body`). A limp joint has ``tau_j = 0``: ``J_j . a_i = 0``. Everything in
it is affine in the limp joints' accelerations (``ddr_i`` through the kinematics,
``dw/dt`` through ``dh/dt``), so with the shape evaluated once at zero and once per
unit acceleration the accelerations solve a small linear system, exactly, the
reaction of the body's rotation on the limb included. The other joints keep
their servo accelerations (the previous step's: the servo's are decided after).

A limp joint whose axis passes through its tip's mass (hip abduction of a limb
stretched along its own axis: ``J_j = 0``) moves no mass; the massless link has no
dynamics, and it is held (acceleration 0) while that lasts.

Ignored: the ground and thrust forces on the tip (a limp limb on the ground is
held by the ground in the contact model; these faults are flight faults).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from splitter_model.joints import LIMB_JOINTS, N_LIMBS, TETHER_INDEX
from splitter_model.kinematics import limb_jacobian
from splitter_sim.core.shape import Shape, ShapeKinematics


def limb_mass_index(limb: int) -> int:
    """The lumped mass (0..9) at the tip of limb ``limb`` (0..7): hemi bodies are 0 and 5."""
    return limb + 1 + limb // 4


def _omega_terms(
    shape: Shape, momentum_body: NDArray[np.float64], gyroscopic_sign: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(w, dw/dt) of the body for a shape and the momentum ``L`` (torque-free)."""
    inertia = shape.inertia_matrix()
    h = np.array(shape.h)
    w = np.linalg.solve(inertia, momentum_body - h)
    inertia_dot = np.array(shape.inertia_dot)
    xx, yy, zz, xy, xz, yz = inertia_dot
    i_dot = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    l_dot = gyroscopic_sign * np.cross(w, momentum_body)
    w_dot = np.linalg.solve(inertia, l_dot - np.array(shape.h_dot) - i_dot @ w)
    return w, w_dot


def tip_torque_residuals(
    kin: ShapeKinematics,
    q: Sequence[float],
    qd: Sequence[float],
    qdd: Sequence[float],
    momentum_body: NDArray[np.float64],
    *,
    joints: Sequence[int],
    gyroscopic_sign: float = -1.0,
) -> NDArray[np.float64]:
    """``J_j . a_i`` [m^2/s^2 per rad] of each joint in ``joints`` at the joint motion (q, qd, qdd).

    Zero for a joint that carries no torque (its torque is ``m_i`` times this).
    """
    shape = kin.evaluate(list(q), list(qd), list(qdd)).relative()
    w, w_dot = _omega_terms(shape, momentum_body, gyroscopic_sign)
    out = np.empty(len(joints))
    for k, j in enumerate(joints):
        limb, which = divmod(j, len(LIMB_JOINTS))
        i = limb_mass_index(limb)
        r = np.array([shape.rx[i], shape.ry[i], shape.rz[i]])
        dr = np.array([shape.vx[i], shape.vy[i], shape.vz[i]])
        ddr = np.array([shape.ax[i], shape.ay[i], shape.az[i]])
        a = ddr + 2.0 * np.cross(w, dr) + np.cross(w_dot, r) + np.cross(w, np.cross(w, r))
        jacobian = limb_jacobian(kin.model, limb, q[3 * limb : 3 * limb + 3])
        out[k] = float(jacobian[:, which] @ a)
    return out


def limp_joint_accelerations(
    kin: ShapeKinematics,
    q: Sequence[float],
    qd: Sequence[float],
    qdd_others: Sequence[float],
    momentum_body: Sequence[float],
    *,
    limp: Sequence[int],
    gyroscopic_sign: float = -1.0,
) -> NDArray[np.float64]:
    """Accelerations [rad/s^2] of the ``limp`` limb joints that make their torques zero.

    ``qdd_others``: the 25 accelerations of the other joints (the limp ones' are
    ignored); ``momentum_body``: ``L`` [kg m^2/s], body frame.
    """
    if any(not 0 <= j < N_LIMBS * len(LIMB_JOINTS) or j == TETHER_INDEX for j in limp):
        raise ValueError(f"limp joints must be limb joints (0..23), got {list(limp)}")
    momentum = np.asarray(momentum_body, dtype=float)
    base = [float(v) for v in qdd_others]
    for j in limp:
        base[j] = 0.0
    out = np.zeros(len(limp))
    moving_mass = [k for k, j in enumerate(limp) if _lever_m(kin, q, j) > LEVER_MIN_M]
    if not moving_mass:
        return out
    limp = [limp[k] for k in moving_mass]
    r0 = tip_torque_residuals(
        kin, q, qd, base, momentum, joints=limp, gyroscopic_sign=gyroscopic_sign
    )
    columns = []
    for j in limp:
        unit = list(base)
        unit[j] = 1.0
        residuals = tip_torque_residuals(
            kin, q, qd, unit, momentum, joints=limp, gyroscopic_sign=gyroscopic_sign
        )
        columns.append(residuals - r0)
    out[moving_mass] = np.linalg.solve(np.column_stack(columns), -r0)
    return out


LEVER_MIN_M = 1e-6  # [m/rad] below this a joint moves no mass (its axis passes through it)


def _lever_m(kin: ShapeKinematics, q: Sequence[float], joint: int) -> float:
    """|d(tip)/d(q_joint)| [m/rad] of a limb joint."""
    limb, which = divmod(joint, len(LIMB_JOINTS))
    jacobian = limb_jacobian(kin.model, limb, q[3 * limb : 3 * limb + 3])
    return float(np.linalg.norm(jacobian[:, which]))
