"""What the hardware can reach, expressed for the inertial-morphing MPC.

The paper bounds the MPC with a box ``|dI| <= dI_max``, ``0 < I <= I_max`` and
leaves both numbers open (section VI.D). Here they are derived from the one
:class:`~splitter_model.model.RobotModel`, and the MPC also constrains what the
box cannot express (section VI.D itself notes the bound is "a circle" in radius
space):

* radius bounds: ``r_i^2`` is *linear* in the principal moments (the radicands of
  the paper's closed form, eq. 3), so ``r_min^2 <= s_i(I) <= r_max^2`` is an exact,
  linear description of every inertia the tether and limbs can produce (the one
  :class:`~splitter_model.reachable.ReachableSet`, shared with the allocator);
* radius rates: ``|r_i(I_{k+1}) - r_i(I_k)| <= v_i dt`` with the reel speed for
  ``r_x`` and the slowest radial limb-tip speed for ``r_y``, ``r_z``;
* tether tension ``T = m_x r_x (w_y^2 + w_z^2) >= T_min`` (taut tether,
  :func:`splitter_model.model.tether_tension_3d`), as a soft constraint.

The box ``dI_max``, ``[I_min, I_max]`` is kept (the paper's form, cheap simple
bounds for the solver); it is the hull of the radius constraints above.
Everything here is ROS-free and numpy-only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.model import RobotModel
from splitter_model.reachable import ReachableSet, reachable_set

# Knee samples used to find the slowest radial tip speed over the knee range.
_KNEE_SAMPLES = 2001


def limb_radial_speed_max_m_s(model: RobotModel) -> float:
    """Radial limb-tip speed every knee angle in range can reach [m/s].

    Moving the tip along its outward axis needs the knee at ``dq3`` and the hip
    pitch at ``dq2 = -d/dq3 atan2(L2 sin q3, L1 + L2 cos q3) dq3``; the faster of
    the two runs at the actuator limit. The radial speed per unit knee rate,
    ``L1 L2 sin(q3) / reach(q3)``, is smallest at the stretched end of the range, so
    the minimum over the range is the speed the MPC may assume anywhere.
    """
    l1, l2 = model.thigh_length_m, model.shank_length_m
    knee = np.linspace(model.knee_min_rad, model.knee_max_rad, _KNEE_SAMPLES)
    reach_sq = l1 * l1 + l2 * l2 + 2.0 * l1 * l2 * np.cos(knee)
    dreach_dknee = l1 * l2 * np.sin(knee) / np.sqrt(reach_sq)  # [m/rad]
    dpitch_dknee = np.abs((l2 * l2 + l1 * l2 * np.cos(knee)) / reach_sq)  # [rad/rad]
    knee_rate = model.joint_speed_max_rad_s / np.maximum(1.0, dpitch_dknee)  # [rad/s]
    return float(np.min(dreach_dknee * knee_rate))


@dataclass(frozen=True)
class MorphingLimits:
    """Bounds of the inertial-morphing MPC, all derived from a :class:`RobotModel`.

    Per-axis arrays are ordered (x, y, z): radii (r_x, r_y, r_z), moments
    (Ixx, Iyy, Izz). Radius and inertia bounds are the model's
    :class:`~splitter_model.reachable.ReachableSet` (``reachable``).
    """

    dt_s: float  # [s] MPC prediction step the per-step bounds refer to
    reachable: ReachableSet  # radius bounds, I = A s, s = R I
    radius_rate_max_m_s: NDArray[np.float64]  # (3,) [m/s]
    inertia_step_max_kg_m2: NDArray[np.float64]  # (3,) [kg m^2] dI_max per step dt
    body_mass_kg: float  # [kg] m_x, for the tension constraint
    tension_min_n: float  # [N]

    @property
    def radius_min_m(self) -> NDArray[np.float64]:
        """(3,) [m] lower radius bounds."""
        return self.reachable.radius_min_m

    @property
    def radius_max_m(self) -> NDArray[np.float64]:
        """(3,) [m] upper radius bounds."""
        return self.reachable.radius_max_m

    @property
    def inertia_min_kg_m2(self) -> NDArray[np.float64]:
        """(3,) [kg m^2] ``I_min``: eq. (2) at the smallest radii."""
        return self.reachable.inertia_min_kg_m2

    @property
    def inertia_max_kg_m2(self) -> NDArray[np.float64]:
        """(3,) [kg m^2] ``I_max``: eq. (2) at the largest radii."""
        return self.reachable.inertia_max_kg_m2

    @property
    def radius_squared_matrix(self) -> NDArray[np.float64]:
        """(3, 3) [1/kg] R with ``s = R I`` (eq. 3 radicands)."""
        return self.reachable.radius_squared_matrix

    @property
    def radius_step_max_m(self) -> NDArray[np.float64]:
        """Largest radius change in one prediction step [m]."""
        return self.radius_rate_max_m_s * self.dt_s

    def radii_squared(self, inertia_kg_m2: ArrayLike) -> NDArray[np.float64]:
        """(r_x^2, r_y^2, r_z^2) [m^2] of principal moments (negative if infeasible)."""
        return self.reachable.radii_squared(inertia_kg_m2)

    def is_reachable(self, inertia_kg_m2: ArrayLike, tol_m2: float = 1e-9) -> bool:
        """True when the moments come from radii inside the hardware bounds."""
        return self.reachable.contains(inertia_kg_m2, tol_m2)


def morphing_limits(
    model: RobotModel,
    dt_s: float,
    tension_min_n: float = 1.0,
    radius_rate_scale: float = 1.0,
) -> MorphingLimits:
    """Derive the MPC bounds from the hardware.

    * ``r_x`` in [tether_length_min/2, tether_length_max/2]: [0.5, 3.0] m; the
      reel pays out the tether (= 2 r_x) at ``tether_speed_max_m_s`` (1.68 m/s), so
      ``r_x`` moves at most 0.84 m/s.
    * ``r_y``, ``r_z`` in the knee's reach [0.107, 0.397] m; the radial tip speed
      is :func:`limb_radial_speed_max_m_s` (2.09 m/s at the stretched end).
    * ``I_min``/``I_max``: eq. (2) at the smallest/largest radii
      (Ixx 0.137..1.891, Iyy = Izz 4.57..162.95 kg m^2 with the paper's masses).
    * ``dI_max``: eq. (2) differentiated, every radius at its largest value moving
      at its top speed, times ``dt`` (0.199, 1.007, 1.007 kg m^2 per 10 ms step).
      It is the loosest rate any reachable configuration allows; the radius-rate
      constraints are the exact, state-dependent ones.

    ``radius_rate_scale`` (0, 1] derates the actuator speeds (margin for the
    allocator's tracking lag); ``tension_min_n`` is the taut-tether margin.
    """
    if not (math.isfinite(dt_s) and dt_s > 0.0):
        raise ValueError(f"dt_s must be finite and > 0, got {dt_s}")
    if not 0.0 < radius_rate_scale <= 1.0:
        raise ValueError(f"radius_rate_scale must be in (0, 1], got {radius_rate_scale}")
    if not (math.isfinite(tension_min_n) and tension_min_n >= 0.0):
        raise ValueError(f"tension_min_n must be finite and >= 0, got {tension_min_n}")
    reachable = reachable_set(model)
    r_max = reachable.radius_max_m
    v_limb = limb_radial_speed_max_m_s(model)
    rate = radius_rate_scale * np.array([model.tether_speed_max_m_s / 2.0, v_limb, v_limb])
    mx, my, mz = model.body_mass_kg, model.limb_mass_y_kg, model.limb_mass_z_kg
    m_tether = 2.0 * mx + 4.0 * my + 4.0 * mz
    # d/dt of eq. (2): dIxx = 8 my ry dry + 8 mz rz drz, dIyy = 2 Mt rx drx + 8 mz rz drz, ...
    x_term = 2.0 * m_tether * r_max[0] * rate[0]
    y_term = 8.0 * my * r_max[1] * rate[1]
    z_term = 8.0 * mz * r_max[2] * rate[2]
    step_max = dt_s * np.array([y_term + z_term, x_term + z_term, x_term + y_term])
    return MorphingLimits(
        dt_s=dt_s,
        reachable=reachable,
        radius_rate_max_m_s=rate,
        inertia_step_max_kg_m2=step_max,
        body_mass_kg=mx,
        tension_min_n=tension_min_n,
    )


def project_to_reachable(limits: MorphingLimits, inertia_kg_m2: ArrayLike) -> NDArray[np.float64]:
    """Nearest reachable moments [kg m^2] (:meth:`ReachableSet.project`, Euclidean)."""
    reachable = limits.reachable
    return reachable.inertia(reachable.project(inertia_kg_m2))


def axis_inertia_range(limits: MorphingLimits, axis: ArrayLike) -> tuple[float, float]:
    """Smallest and largest moment ``e' I e`` [kg m^2] about the body axis ``e`` within reach."""
    return limits.reachable.axis_inertia_range(axis)
