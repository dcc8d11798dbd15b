"""Spring-damper ground contact with a regularised Coulomb friction cone (paper section V).

Each lumped mass touching the plane ``z = 0`` (world, z up) feels

* a normal force ``F_n = s delta + c d(delta)/dt`` (paper eq. for F_c), with the
  penetration ``delta = -z`` and ``F_n`` clamped at 0 (the ground pushes, never pulls);
* a tangential force opposing the slip velocity ``v_t``:
  ``F_t = -min(c_t |v_t|, mu F_n) v_t / |v_t|``.

The friction law is Coulomb's cone with a viscous regularisation near zero slip
(slope ``c_t``): it never leaves the cone (``|F_t| <= mu F_n`` by construction),
needs no per-contact state (so it integrates inside RK4 stages), and its slope
is finite so the explicit integrator stays stable. The price is creep: a
tangential load ``F`` below the cone slides at ``F / c_t`` (documented with the
defaults in :class:`splitter_sim.core.simulator.SimConfig`).
"""

from __future__ import annotations

import math


def ground_contact_force(  # noqa: PLR0917  (hot path: positional floats are fastest)
    z_m: float,
    vx_m_s: float,
    vy_m_s: float,
    vz_m_s: float,
    stiffness_n_m: float,
    damping_n_s_m: float,
    friction_coefficient: float,
    friction_damping_n_s_m: float,
) -> tuple[float, float, float]:
    """World-frame ground force [N] on a point at height ``z_m`` moving at ``v``.

    Zero when the point is above the ground or separating fast enough that the
    damper would pull.
    """
    if z_m >= 0.0:
        return 0.0, 0.0, 0.0
    normal = -stiffness_n_m * z_m - damping_n_s_m * vz_m_s
    if normal <= 0.0:
        return 0.0, 0.0, 0.0
    slip = math.hypot(vx_m_s, vy_m_s)
    if slip == 0.0:
        return 0.0, 0.0, normal
    cone = friction_coefficient * normal
    viscous = friction_damping_n_s_m * slip
    scale = -(viscous if viscous < cone else cone) / slip
    return scale * vx_m_s, scale * vy_m_s, normal


def static_penetration_m(weight_n: float, n_contacts: int, stiffness_n_m: float) -> float:
    """Penetration [m] at rest when ``n_contacts`` springs share ``weight_n`` equally."""
    return weight_n / (n_contacts * stiffness_n_m)


def contact_natural_frequency_rad_s(stiffness_n_m: float, effective_mass_kg: float) -> float:
    """Undamped natural frequency [rad/s] of one contact spring on ``effective_mass_kg``."""
    return math.sqrt(stiffness_n_m / effective_mass_kg)
