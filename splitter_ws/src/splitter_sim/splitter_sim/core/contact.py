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
from collections.abc import Callable, Sequence
from typing import Any


def ground_contact_force(  # noqa: PLR0917  (hot path: positional floats are fastest)
    z_m: Any,
    vx_m_s: Any,
    vy_m_s: Any,
    vz_m_s: Any,
    stiffness_n_m: Any,
    damping_n_s_m: Any,
    friction_coefficient: Any,
    friction_damping_n_s_m: Any,
    ops: Any = None,
) -> tuple[Any, Any, Any]:
    """World-frame ground force [N] on a point at height ``z_m`` moving at ``v``.

    Zero when the point is above the ground or separating fast enough that the
    damper would pull. ``ops`` None: floats, the law's branches are taken. Else
    the CasADi symbols of the simulator's compiled kernels (:mod:`.kernels`):
    ``ops`` has casadi's ``hypot``, ``if_else`` and ``logic_and``, and every
    branch is a selection (the same formulas in the same order).
    """
    normal = -stiffness_n_m * z_m - damping_n_s_m * vz_m_s
    if ops is None and (z_m >= 0.0 or normal <= 0.0):
        return 0.0, 0.0, 0.0
    slip = math.hypot(vx_m_s, vy_m_s) if ops is None else ops.hypot(vx_m_s, vy_m_s)
    if ops is None and slip == 0.0:
        return 0.0, 0.0, normal
    cone = friction_coefficient * normal
    viscous = friction_damping_n_s_m * slip
    if ops is None:
        scale = -(viscous if viscous < cone else cone) / slip
        return scale * vx_m_s, scale * vy_m_s, normal
    scale = -ops.if_else(viscous < cone, viscous, cone) / slip
    pressed = ops.logic_and(z_m < 0.0, normal > 0.0)
    sliding = ops.logic_and(pressed, slip != 0.0)
    return (
        ops.if_else(sliding, scale * vx_m_s, 0.0),
        ops.if_else(sliding, scale * vy_m_s, 0.0),
        ops.if_else(pressed, normal, 0.0),
    )


def mass_heights_m(
    pz_m: Any, r2: Sequence[Any], rx: Sequence[Any], ry: Sequence[Any], rz: Sequence[Any]
) -> list[Any]:
    """World height [m] of each mass: COM height ``pz_m`` plus the third row ``r2`` of the
    rotation (world <- base) times the mass's position ``(rx, ry, rz)`` from the COM (base)."""
    r20, r21, r22 = r2
    return [pz_m + r20 * x + r21 * y + r22 * z for x, y, z in zip(rx, ry, rz, strict=True)]


def contact_reach_m(  # noqa: PLR0917  (as the kernels' symbols)
    v_m_s: Sequence[Any],
    w_rad_s: Sequence[Any],
    radius_m: Any,
    mass_speed_max_m_s: Any,
    dt_s: Any,
    gravity_m_s2: Any,
    sqrt: Callable[[Any], Any] = math.sqrt,
) -> Any:
    """Height [m] below which a mass may reach the ground within a step of ``dt_s``.

    A generous bound on how far a mass can fall within the step (speeds may double):
    the COM speed, the rotation's ``|w| radius`` and the joints' fastest mass motion.
    """
    vx, vy, vz = v_m_s
    wx, wy, wz = w_rad_s
    speed = (
        sqrt(vx * vx + vy * vy + vz * vz)
        + sqrt(wx * wx + wy * wy + wz * wz) * radius_m
        + mass_speed_max_m_s
    )
    return 2.0 * speed * dt_s + (gravity_m_s2 + 100.0) * dt_s * dt_s


def static_penetration_m(weight_n: float, n_contacts: int, stiffness_n_m: float) -> float:
    """Penetration [m] at rest when ``n_contacts`` springs share ``weight_n`` equally."""
    return weight_n / (n_contacts * stiffness_n_m)


def contact_natural_frequency_rad_s(stiffness_n_m: float, effective_mass_kg: float) -> float:
    """Undamped natural frequency [rad/s] of one contact spring on ``effective_mass_kg``."""
    return math.sqrt(stiffness_n_m / effective_mass_kg)
