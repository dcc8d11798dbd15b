"""Spring-damper ground contact with a regularised Coulomb friction cone (paper section V).

Each lumped mass touching the ground (the plane ``z = 0``, world z up, or the plane
of :class:`splitter_model.terrain.Terrain` it touches, of normal ``n``) feels

* a normal force ``F_n = s delta + c d(delta)/dt`` along ``n`` (paper eq. for F_c),
  with the penetration ``delta`` (minus the signed distance to the plane) and ``F_n``
  clamped at 0 (the ground pushes, never pulls);
* a tangential force opposing the slip velocity ``v_t`` (along the plane):
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
    nx: Any = 0.0,
    ny: Any = 0.0,
    nz: Any = 1.0,
    ops: Any = None,
) -> tuple[Any, Any, Any]:
    """World-frame ground force [N] on a point ``z_m`` from the ground moving at ``v``.

    ``z_m`` is the point's signed distance to the ground plane of unit normal ``n``
    (world; default the level ground, ``z_m`` then the height): the normal force acts
    along ``n`` with the normal speed ``n . v``, friction against the slip ``v - (n . v) n``.
    Zero when the point is off the ground or separating fast enough that the
    damper would pull. ``ops`` None: floats, the law's branches are taken. Else
    the CasADi symbols of the simulator's compiled kernels (:mod:`.kernels`):
    ``ops`` has casadi's ``hypot``, ``if_else`` and ``logic_and``, and every
    branch is a selection (the same formulas in the same order; on level ground
    they give the level law's numbers exactly).
    """
    if ops is None and nx == 0.0 and ny == 0.0 and nz == 1.0:
        return _level_contact_force(
            z_m,
            vx_m_s,
            vy_m_s,
            vz_m_s,
            stiffness_n_m,
            damping_n_s_m,
            friction_coefficient,
            friction_damping_n_s_m,
        )
    v_n = nx * vx_m_s + ny * vy_m_s + nz * vz_m_s
    normal = -stiffness_n_m * z_m - damping_n_s_m * v_n
    if ops is None and (z_m >= 0.0 or normal <= 0.0):
        return 0.0, 0.0, 0.0
    tx, ty, tz = vx_m_s - v_n * nx, vy_m_s - v_n * ny, vz_m_s - v_n * nz
    hypot = math.hypot if ops is None else ops.hypot
    slip = hypot(hypot(tx, ty), tz)
    cone = friction_coefficient * normal
    viscous = friction_damping_n_s_m * slip
    if ops is None:
        if slip == 0.0:
            return normal * nx, normal * ny, normal * nz
        scale = -(viscous if viscous < cone else cone) / slip
        return scale * tx + normal * nx, scale * ty + normal * ny, scale * tz + normal * nz
    scale = -ops.if_else(viscous < cone, viscous, cone) / slip
    pressed = ops.logic_and(z_m < 0.0, normal > 0.0)
    sliding = ops.logic_and(pressed, slip != 0.0)
    return (
        ops.if_else(sliding, scale * tx, 0.0) + ops.if_else(pressed, normal * nx, 0.0),
        ops.if_else(sliding, scale * ty, 0.0) + ops.if_else(pressed, normal * ny, 0.0),
        ops.if_else(sliding, scale * tz, 0.0) + ops.if_else(pressed, normal * nz, 0.0),
    )


def _level_contact_force(  # noqa: PLR0917  (as ground_contact_force)
    z_m: float,
    vx_m_s: float,
    vy_m_s: float,
    vz_m_s: float,
    stiffness_n_m: float,
    damping_n_s_m: float,
    friction_coefficient: float,
    friction_damping_n_s_m: float,
) -> tuple[float, float, float]:
    """:func:`ground_contact_force` on level ground, with floats (the hot path)."""
    normal = -stiffness_n_m * z_m - damping_n_s_m * vz_m_s
    if z_m >= 0.0 or normal <= 0.0:
        return 0.0, 0.0, 0.0
    slip = math.hypot(vx_m_s, vy_m_s)
    if slip == 0.0:
        return 0.0, 0.0, normal
    cone = friction_coefficient * normal
    viscous = friction_damping_n_s_m * slip
    scale = -(viscous if viscous < cone else cone) / slip
    return scale * vx_m_s, scale * vy_m_s, normal


def mass_heights_m(  # noqa: PLR0917  (as the kernels' symbols)
    p_m: Sequence[Any],
    rotation: Sequence[Any],
    rx: Sequence[Any],
    ry: Sequence[Any],
    rz: Sequence[Any],
    planes: Sequence[Sequence[Any]] | None = None,
) -> list[Any]:
    """Signed distance [m] of each mass to its ground plane (``planes``: (nx, ny, nz, d)
    per mass; None: its world height above z = 0).

    The mass is at the COM ``p_m`` plus the ``rotation`` (world <- base, 9 entries row
    by row) of its position ``(rx, ry, rz)`` from the COM (base). The same arithmetic
    as :func:`splitter_sim.core.rigid_body.external_load`.
    """
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = rotation
    px, py, pz = p_m
    heights = [pz + r20 * x + r21 * y + r22 * z for x, y, z in zip(rx, ry, rz, strict=True)]
    if planes is None:
        return heights
    return [
        nx * (px + r00 * x + r01 * y + r02 * z)
        + ny * (py + r10 * x + r11 * y + r12 * z)
        + nz * height
        - d
        for (nx, ny, nz, d), x, y, z, height in zip(planes, rx, ry, rz, heights, strict=True)
    ]


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
