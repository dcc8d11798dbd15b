"""Tether tension while reeling, and the outward acceleration that keeps it taut.

Radial dynamics of Hemi-SPLITTER ``a`` (at ``+r_x`` on the body x axis) in torque-free
flight, in the frame falling with the centre of mass (gravity cancels). Every
lumped mass of the hemi, body ``m_x`` and limb tips ``m_y``, ``m_z``, sits at
``x = r_x``; summing the x components of their inertial accelerations
``P'' + 2 w x P' + w' x P + w x (w x P)`` over the hemi, the limb terms cancel in
+-pairs and what is left is::

    M_h (r_x'' - r_x w_perp^2) = -T,   w_perp^2 = w_y^2 + w_z^2,
    M_h = m_x + 2 m_y + 2 m_z  (the whole hemi: its limbs ride on its body)

so ``T = M_h (r_x w_perp^2 - r_x'')``: the steady part is
``splitter_model.model.tether_tension_3d``, reeling adds ``-M_h r_x''``. The
tether can only pull: it stays taut with at least ``T_min`` while
``r_x'' <= r_x w_perp^2 - T_min / M_h``. (The paper's ``T = m_x w_y^2 r_x`` counts
the body mass alone, a third of the load for its masses; the sign, hence the
taut condition, is the same.)
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from splitter_model.model import RobotModel, tether_tension_3d


def hemi_mass_kg(model: RobotModel) -> float:
    """M_h = m_x + 2 m_y + 2 m_z [kg]: the mass the tether holds on each side."""
    return model.hemi_mass_kg


def perpendicular_spin_squared(angular_velocity_rad_s: ArrayLike) -> float:
    """w_perp^2 = w_y^2 + w_z^2 [rad^2/s^2]: spin about axes across the tether."""
    w = np.asarray(angular_velocity_rad_s, dtype=float).reshape(3)
    return float(w[1] ** 2 + w[2] ** 2)


def reeling_tether_tension(
    model: RobotModel,
    angular_velocity_rad_s: ArrayLike,
    radius_x_m: float,
    radius_x_acceleration_m_s2: float = 0.0,
) -> float:
    """T = M_h (r_x w_perp^2 - r_x'') [N]; negative means the tether would go slack."""
    steady = tether_tension_3d(model, angular_velocity_rad_s, radius_x_m)
    return steady - model.hemi_mass_kg * radius_x_acceleration_m_s2


def max_taut_radius_acceleration(
    model: RobotModel,
    angular_velocity_rad_s: ArrayLike,
    radius_x_m: float,
    tension_min_n: float,
) -> float:
    """Largest r_x'' [m/s^2] keeping the tension at or above ``tension_min_n`` [N]."""
    w_perp2 = perpendicular_spin_squared(angular_velocity_rad_s)
    return radius_x_m * w_perp2 - tension_min_n / model.hemi_mass_kg
