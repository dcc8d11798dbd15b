"""Compliant legs: the stance force of a hemi's four legs under impedance control (ROS-free).

The lumped model has no leg masses of its own: a hemi's legs reach
``SimConfig.thrust_stroke_m`` (the paper's 0.4 m limb) below its lowest lumped
mass, the stroke the jump thrust is pushed over (paper section IV). With
compliant legs the same stroke absorbs a touchdown: while the lowest mass of a
hemi is within the stroke of the ground, its legs are compressed by
``stroke - height`` and push on the hemi body with

* normal force ``F_n = k x + c v_down``, never pulling (>= 0), at most
  ``force_max`` (the limbs' dynamic limit: the paper's 20 kg payload per
  quadruped, about 196 N, section VII.C);
* tangential force ``-c_t v_t`` (the hip's impedance with the feet planted),
  within the friction cone ``mu F_n`` and within what ``force_max`` leaves of
  the force's norm (the normal force has priority: it keeps the body off the
  ground).

``x`` is the leg compression [m], ``v_down`` the hemi body's downward speed
[m/s] and ``v_t`` its horizontal velocity [m/s]. A weak spring (the standing
robot rests crouched, ready to push) and a strong damper make a touchdown an
almost constant-force stop at ``force_max``: 9 kg from 3.9 m/s within the 0.4 m
stroke at 190 N. The lumped masses touch the ground only when a leg is fully
compressed (the spring-damper ground of :mod:`splitter_sim.core.rigid_body`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class LegImpedance:
    """Impedance of one hemi's legs in stance (all four together)."""

    stiffness_n_m: float  # k [N/m]
    damping_n_s_m: float  # c [N s/m] along the vertical
    tangential_damping_n_s_m: float  # c_t [N s/m] horizontal
    friction_coefficient: float  # mu [-] of the feet on the ground
    force_max_n: float  # [N] largest norm of the stance force

    def __post_init__(self) -> None:
        for name in (
            "stiffness_n_m",
            "damping_n_s_m",
            "tangential_damping_n_s_m",
            "friction_coefficient",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"LegImpedance.{name} must be finite and >= 0, got {value!r}")
        if not (math.isfinite(self.force_max_n) and self.force_max_n > 0.0):
            raise ValueError(
                f"LegImpedance.force_max_n must be finite and > 0, got {self.force_max_n}"
            )


def leg_stance_force(
    compression_m: float,
    velocity_world_m_s: tuple[float, float, float],
    legs: LegImpedance,
) -> tuple[float, float, float]:
    """World force [N] of a hemi's legs compressed by ``compression_m`` (<= 0: no contact).

    ``velocity_world_m_s`` is the hemi body's velocity [m/s]. Module docstring
    for the law; the result's norm never exceeds ``legs.force_max_n``.
    """
    if compression_m <= 0.0:
        return 0.0, 0.0, 0.0
    vx, vy, vz = velocity_world_m_s
    normal = legs.stiffness_n_m * compression_m - legs.damping_n_s_m * vz
    normal = min(max(normal, 0.0), legs.force_max_n)
    if normal == 0.0:
        return 0.0, 0.0, 0.0
    speed_t = math.hypot(vx, vy)
    if speed_t == 0.0:
        return 0.0, 0.0, normal
    tangential = min(
        legs.tangential_damping_n_s_m * speed_t,
        legs.friction_coefficient * normal,
        math.sqrt(max(legs.force_max_n * legs.force_max_n - normal * normal, 0.0)),
    )
    scale = -tangential / speed_t
    return scale * vx, scale * vy, normal
