"""Radial limb kinematics the allocator needs beyond ``splitter_model.kinematics``.

A limb in a *radial* configuration (zero abduction, tip on the limb's outward axis,
see ``splitter_model.kinematics.radial_limb_joint_angles``) is fully described
by its knee angle ``k``: the tip radius is ``r(k) = sqrt(l1^2 + l2^2 + 2 l1 l2 cos k)``
(``RobotModel.limb_reach_m``) and the hip pitch is
``q2(k) = -atan2(l2 sin k, l1 + l2 cos k)``. This module gives the inverse
``k(r)`` and the derivatives (the radial "knee Jacobian") that turn a radius
rate into joint velocities. ROS-free, math only.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.actuators import TETHER_INDEX
from splitter_model.model import RobotModel

# Relative slack accepted on a radius at the edge of the knee range (rounding of r(k)).
_REACH_TOLERANCE = 1e-12


def knee_from_radius(model: RobotModel, radius_m: float) -> float:
    """Knee angle [rad] placing a radial limb tip at ``radius_m`` [m].

    Raises ``ValueError`` when the radius is outside the knee's reach.
    """
    r_min, r_max = model.limb_radius_min_m, model.limb_radius_max_m
    if not (
        math.isfinite(radius_m) and r_min - _REACH_TOLERANCE <= radius_m <= r_max + _REACH_TOLERANCE
    ):
        raise ValueError(f"limb radius {radius_m} m is outside [{r_min:.6f}, {r_max:.6f}] m")
    l1, l2 = model.thigh_length_m, model.shank_length_m
    cos_knee = (radius_m * radius_m - l1 * l1 - l2 * l2) / (2.0 * l1 * l2)
    knee = math.acos(min(1.0, max(-1.0, cos_knee)))
    return min(model.knee_max_rad, max(model.knee_min_rad, knee))


def radius_from_knee(model: RobotModel, knee_rad: float) -> float:
    """Tip radius [m] of a radial limb with knee angle ``knee_rad``."""
    return model.limb_reach_m(knee_rad)


def radial_hip_pitch(model: RobotModel, knee_rad: float) -> float:
    """Hip pitch [rad] that keeps the tip on the outward axis for ``knee_rad``."""
    l1, l2 = model.thigh_length_m, model.shank_length_m
    return -math.atan2(l2 * math.sin(knee_rad), l1 + l2 * math.cos(knee_rad))


def radius_rate_per_knee_rate(model: RobotModel, knee_rad: float) -> float:
    """dr/dk [m/rad] of a radial limb: ``-l1 l2 sin(k) / r(k)`` (negative: folding shortens)."""
    l1, l2 = model.thigh_length_m, model.shank_length_m
    return -l1 * l2 * math.sin(knee_rad) / model.limb_reach_m(knee_rad)


def hip_pitch_rate_per_knee_rate(model: RobotModel, knee_rad: float) -> float:
    """dq2/dk [-] of a radial limb: ``-(l2^2 + l1 l2 cos k) / r(k)^2``.

    Exactly -1/2 for equal thigh and shank (the hip turns half as fast as the knee).
    """
    l1, l2 = model.thigh_length_m, model.shank_length_m
    c = math.cos(knee_rad)
    return -(l2 * l2 + l1 * l2 * c) / (l1 * l1 + l2 * l2 + 2.0 * l1 * l2 * c)


def hip_pitch_speed_ratio_max(model: RobotModel) -> float:
    """max |dq2/dk| over the knee range [-].

    dq2/dk is a Moebius function of cos k, monotone between the range ends, so the
    maximum is at ``knee_min_rad`` or ``knee_max_rad``.
    """
    return max(
        abs(hip_pitch_rate_per_knee_rate(model, model.knee_min_rad)),
        abs(hip_pitch_rate_per_knee_rate(model, model.knee_max_rad)),
    )


def radial_limb_joint_rates(
    model: RobotModel, radius_m: float, radius_rate_m_s: float
) -> NDArray[np.float64]:
    """(hip_abduction, hip_pitch, knee) rates [rad/s] of a radial limb changing radius.

    The knee Jacobian: ``dk/dt = dr/dt / (dr/dk)``, ``dq2/dt = dq2/dk * dk/dt``.
    Raises ``ValueError`` at a stretched or folded singularity (``sin k = 0``).
    """
    knee = knee_from_radius(model, radius_m)
    dr_dk = radius_rate_per_knee_rate(model, knee)
    if abs(dr_dk) < 1e-12:
        raise ValueError(f"radial limb at knee {knee} rad is singular (dr/dk = 0)")
    knee_rate = radius_rate_m_s / dr_dk
    return np.array([0.0, hip_pitch_rate_per_knee_rate(model, knee) * knee_rate, knee_rate])


def joint_velocities_from_radii_rate(
    model: RobotModel, radii_m: ArrayLike, radii_rate_m_s: ArrayLike
) -> NDArray[np.float64]:
    """All 25 joint velocities (order of ``names.JOINT_NAMES``) for symmetric radii rates.

    Limb joints [rad/s] from the knee Jacobian; tether [m/s] = 2 dr_x/dt.
    """
    r = np.asarray(radii_m, dtype=float).reshape(3)
    rdot = np.asarray(radii_rate_m_s, dtype=float).reshape(3)
    rates_y = radial_limb_joint_rates(model, float(r[1]), float(rdot[1]))
    rates_z = radial_limb_joint_rates(model, float(r[2]), float(rdot[2]))
    qdot = np.zeros(25)
    for limb in range(8):
        qdot[3 * limb : 3 * limb + 3] = rates_y if limb % 4 < 2 else rates_z
    qdot[TETHER_INDEX] = 2.0 * rdot[0]
    return qdot
