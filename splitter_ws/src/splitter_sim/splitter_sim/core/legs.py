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

Legs act where they point. A hemi's legs are mounted under its belly: they reach
along the hemi's leg axis, body ``-z`` (the robot stands with body ``+z`` up), and
push the body along body ``+z``. They reach the ground only while the belly faces
it: the angle between body ``+z`` and the ground normal must stay within the
workspace cone ``cone_half_angle_deg`` (default 60 deg, README "Legs that act where
they point": a leg of the paper's 0.4 m clears the edge of a 0.2 m half-wide body
while ``90 deg - asin(0.2 / 0.4)``). Outside the cone the legs neither push nor
absorb: the hemi lands on its body, the stiff ground of the lumped masses. Tilted
within the cone, the compression is measured along the leg axis and the law above
acts along it; the ground then takes the force only within its friction cone (the
feet slip beyond: the force's part along the ground is cut to ``mu`` times its
part along the normal).

Ride height (posture). A weak spring alone leaves a hemi standing crouched, its lowest
mass 3 cm above the ground; after a touchdown it slides on so (lunar friction brakes
2 m/s over about 1.5 m), and any step higher than that in the slide is struck by a
limb tip (measured: 637 N from a 5 cm step at 0.6 m/s). The stroke cannot brake the
slide either: stopping the nominal 3.6 m/s touchdown within it takes 189 N of the
190 N cap. So the legs stand the hemi at a ride height (``posture_stiffness`` > 0): the
posture ``W + k_p (x - x_ride) - c_p v_n`` holds the nominal hemi's weight ``W`` at the
ride compression ``x_ride`` (the lowest mass ``stroke - x_ride`` up). A hemi coming down
faster than ``LANDING_SPEED_M_S`` (a touchdown) also gets the spring-damper's stop
where that is stronger. Before a push the legs crouch (the simulator sets ``crouch``
once a jump is commanded): the posture's set point moves to the crouch compression,
the hemi sinks under its weight, the legs still carrying half of it
(``CROUCH_LOAD_FRACTION``: 0.67 s for 0.18 m on the Moon, the feet kept loaded), and
the push starts from there, over the stroke a crouched robot has.

The whole stroke (``stop_mass_kg`` > 0). The damper alone saturates the cap only
above ``force_max / c`` (0.95 m/s): below it the force falls off and the end of a fast
stop is spent at less than the cap, so a 9 kg hemi bottoms its 0.4 m stroke from
3.86 m/s where a constant 190 N stops it from 3.95 m/s
(``v_max = sqrt(2 s (F_max / m - g))``). A hemi coming down is therefore also given
the force that stops it at the end of the stroke, ``m (g + v^2 / (2 d))`` with ``d``
the stroke left (less ``stop_reserve_m``), wherever that is stronger than the law
above; ``m`` is the nominal hemi's mass the leg controller knows (not the simulated
robot's). It is a feedback on the stroke left: with a heavier hemi than ``m`` the
required force grows as ``d`` shrinks, up to the cap. A touchdown the damper stops
within the stroke is not changed: the law is stronger all along it (the nominal
3.63 m/s lunar touchdown uses 0.36 m either way). A crouch (below) is not stopped: it
lowers the hemi to the stroke's end on purpose.

Posture about the tether axis. The two hemis stand on the tether axis, so forces at
the hemi bodies alone would leave the robot free to roll about it (measured: a robot
standing after a spinning touchdown rolled over in 1.5 s, its y limb tips caught by
the ground while it slid). A hemi's four feet spread sideways under its y limbs, a
lever ``b`` (the y limb's reach) either side: the legs level the body by shifting
load between the left and right feet (:func:`roll_load_share`), a moment
``-k_roll sin(roll) - c_roll w_x`` about body x, at most the whole load on one side
(``b`` times the load: the edge of the support polygon, where a real robot tips).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

# [m/s] with a posture, the spring-damper's landing stop acts on a hemi coming down
# faster than the first speed, wholly from the second (a touchdown; a crouch is slower)
LANDING_SPEED_M_S = (0.5, 1.0)
_LANDING_BLEND = LANDING_SPEED_M_S[1] - LANDING_SPEED_M_S[0]
# [m/s] the whole-stroke stop grows in from rest to this speed coming down. At rest it
# would hold the nominal hemi's weight, not the robot's, and switch on and off with the
# sign of the speed: a lighter hemi chattered (12.3 / 14.7 N, +-0.07 m/s^2 at the
# accelerometer), so the gait never saw the robot at rest and never declared LANDED.
STOP_BLEND_SPEED_M_S = 0.1
# [-] a crouching hemi's legs carry at least this share of its weight: it sinks at no
# more than half of g (0.18 m in 0.67 s on the Moon) and its feet stay on the ground
CROUCH_LOAD_FRACTION = 0.5


@dataclass(frozen=True)
class LegImpedance:
    """Impedance of one hemi's legs in stance (all four together)."""

    stiffness_n_m: float  # k [N/m]
    damping_n_s_m: float  # c [N s/m] along the vertical
    tangential_damping_n_s_m: float  # c_t [N s/m] horizontal
    friction_coefficient: float  # mu [-] of the feet on the ground
    force_max_n: float  # [N] largest norm of the stance force
    cone_half_angle_deg: float = 60.0  # [deg] workspace: belly normal to ground normal
    roll_stiffness_nm_rad: float = 0.0  # [N m/rad] levelling moment about the tether axis
    roll_damping_nm_s_rad: float = 0.0  # [N m s/rad]
    hold_stiffness_n_m: float = 0.0  # [N/m] planted feet: spring to where they stand
    hold_damping_n_s_m: float = 0.0  # [N s/m] along the ground while planted (hip damper)
    # Ride height while sliding (module docstring); posture_stiffness 0: off.
    posture_stiffness_n_m: float = 0.0  # k_p [N/m]
    posture_damping_n_s_m: float = 0.0  # c_p [N s/m]
    posture_weight_n: float = 0.0  # W [N] the nominal hemi's weight the posture holds
    ride_compression_m: float = 0.2  # x_ride [m]
    crouch_compression_m: float = 0.38  # [m] where the legs crouch before a push
    # The whole stroke (module docstring); stop_mass_kg 0: off.
    stop_mass_kg: float = 0.0  # [kg] the nominal hemi the stop is computed for
    stop_gravity_m_s2: float = 0.0  # [m/s^2] gravity the stop also holds
    stroke_m: float = 0.4  # [m] the legs' stroke
    stop_reserve_m: float = 0.01  # [m] of the stroke the stop keeps (one 5 ms step at 2 m/s)

    def __post_init__(self) -> None:
        for name in (
            "stiffness_n_m",
            "damping_n_s_m",
            "tangential_damping_n_s_m",
            "friction_coefficient",
            "roll_stiffness_nm_rad",
            "roll_damping_nm_s_rad",
            "hold_stiffness_n_m",
            "hold_damping_n_s_m",
            "posture_stiffness_n_m",
            "posture_damping_n_s_m",
            "posture_weight_n",
            "ride_compression_m",
            "crouch_compression_m",
            "stop_mass_kg",
            "stop_gravity_m_s2",
            "stroke_m",
            "stop_reserve_m",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"LegImpedance.{name} must be finite and >= 0, got {value!r}")
        if not (math.isfinite(self.force_max_n) and self.force_max_n > 0.0):
            raise ValueError(
                f"LegImpedance.force_max_n must be finite and > 0, got {self.force_max_n}"
            )
        if not (math.isfinite(self.cone_half_angle_deg) and 0.0 < self.cone_half_angle_deg < 90.0):
            raise ValueError(
                "LegImpedance.cone_half_angle_deg must be in (0, 90) deg, "
                f"got {self.cone_half_angle_deg!r}"
            )

    @property
    def cone_cos(self) -> float:
        """Cosine of the workspace cone's half angle [-]."""
        return math.cos(math.radians(self.cone_half_angle_deg))


def legs_face_ground(belly_up_z: float, legs: LegImpedance) -> bool:
    """Whether a hemi whose body ``+z`` has world component ``belly_up_z`` (the cosine of
    its tilt from the ground normal) has its legs within their workspace cone."""
    return belly_up_z >= legs.cone_cos


def leg_compression_m(stroke_m: float, lowest_height_m: float, belly_up_z: float) -> float:
    """Compression [m] of legs of ``stroke_m`` reaching along the leg axis from a hemi whose
    lowest mass is ``lowest_height_m`` above the ground (<= 0: the feet do not touch).

    The ground lies ``lowest_height_m / belly_up_z`` away along the tilted leg axis.
    """
    if belly_up_z <= 0.0:
        return 0.0
    return stroke_m - lowest_height_m / belly_up_z


def leg_normal_force(
    compression_m: float,
    velocity_along_m_s: float,
    legs: LegImpedance,
    crouch: bool = False,
) -> float:
    """Force [N] of legs compressed by ``compression_m`` along their axis, in
    ``[0, force_max_n]`` (module docstring "Ride height").

    ``velocity_along_m_s`` is the hemi's velocity along the leg axis (< 0: coming
    down). Without a posture: the spring-damper ``k x - c v``. With one: the posture
    about the ride compression (``crouch``: about the crouch, a push about to start),
    and coming down faster than ``LANDING_SPEED_M_S`` the spring-damper's stop where
    it is stronger.
    """
    law = legs.stiffness_n_m * compression_m - legs.damping_n_s_m * velocity_along_m_s
    # a crouch lowers the hemi on purpose, to the stroke's end: no stop
    stop = 0.0 if crouch else full_stroke_stop_force(compression_m, velocity_along_m_s, legs)
    if legs.posture_stiffness_n_m == 0.0:
        return min(max(law, stop, 0.0), legs.force_max_n)
    target = legs.crouch_compression_m if crouch else legs.ride_compression_m
    normal = (
        legs.posture_weight_n
        + legs.posture_stiffness_n_m * (compression_m - target)
        - legs.posture_damping_n_s_m * velocity_along_m_s
    )
    if crouch:  # lowered, not dropped: the feet stay loaded
        normal = max(normal, CROUCH_LOAD_FRACTION * legs.posture_weight_n)
    landing = min(max((-velocity_along_m_s - LANDING_SPEED_M_S[0]) / _LANDING_BLEND, 0.0), 1.0)
    if landing > 0.0 and law > normal:
        normal += landing * (law - normal)
    return min(max(normal, stop, 0.0), legs.force_max_n)


def full_stroke_stop_force(
    compression_m: float, velocity_along_m_s: float, legs: LegImpedance
) -> float:
    """Force [N] that stops a hemi coming down at ``-velocity_along_m_s`` [m/s] at the
    end of the stroke (less the reserve): ``m (g + v^2 / (2 d))``, scaled in from rest
    up to ``STOP_BLEND_SPEED_M_S``, or ``force_max_n`` with no stroke left; 0 going up or
    with ``stop_mass_kg`` 0 (module docstring, "The whole stroke")."""
    if legs.stop_mass_kg == 0.0 or velocity_along_m_s >= 0.0:
        return 0.0
    left = legs.stroke_m - legs.stop_reserve_m - compression_m
    if left <= 0.0:
        return legs.force_max_n
    speed = -velocity_along_m_s
    stop = legs.stop_mass_kg * (legs.stop_gravity_m_s2 + speed * speed / (2.0 * left))
    return stop * min(speed / STOP_BLEND_SPEED_M_S, 1.0)


def stroke_left_after_stop_m(
    touchdown_speed_m_s: float,
    hemi_mass_kg: float,
    force_max_n: float,
    gravity_m_s2: float,
    stroke_m: float,
) -> float:
    """Most stroke [m] any leg law leaves under a hemi it stops from ``touchdown_speed_m_s``
    (along the legs) within ``force_max_n``: ``s - v^2 / (2 (F / m - g))``, the stop at
    the cap all the way. Negative: no stroke of ``stroke_m`` stops it within the cap.

    The lowest mass comes down to at most this height above the ground: a step higher
    than it whose edge the hemi meets while it stops strikes the body, whatever the legs
    do (README "Random jumps", the step range)."""
    if not (hemi_mass_kg > 0.0 and force_max_n > hemi_mass_kg * gravity_m_s2):
        raise ValueError(
            f"force_max_n {force_max_n!r} must hold the hemi's weight "
            f"({hemi_mass_kg!r} kg at {gravity_m_s2!r} m/s^2)"
        )
    deceleration = force_max_n / hemi_mass_kg - gravity_m_s2  # [m/s^2]
    return stroke_m - touchdown_speed_m_s * touchdown_speed_m_s / (2.0 * deceleration)


def leg_stance_force(
    compression_m: float,
    velocity_world_m_s: tuple[float, float, float],
    legs: LegImpedance,
    belly_up: tuple[float, float, float] = (0.0, 0.0, 1.0),
    hold_n: tuple[float, float] = (0.0, 0.0),
    *,
    crouch: bool = False,
) -> tuple[float, float, float]:
    """Force [N] of a hemi's legs compressed by ``compression_m`` (<= 0: no contact), in
    the ground's frame (z along the ground normal; on level ground the world).

    ``velocity_world_m_s`` is the hemi body's velocity [m/s], ``belly_up`` the hemi's
    body ``+z`` (unit; the legs push along it), ``hold_n`` the planted feet's spring
    (x, y) [N] along the ground (:func:`foot_hold_force`), ``crouch`` the posture's
    set point (:func:`leg_normal_force`). Module docstring for
    the law; the result's norm never exceeds ``legs.force_max_n`` and the result
    stays within the ground's friction cone.
    """
    if compression_m <= 0.0:
        return 0.0, 0.0, 0.0
    vx, vy, vz = velocity_world_m_s
    nx, ny, nz = belly_up
    if hold_n[0] != 0.0 or hold_n[1] != 0.0:
        return _held_stance_force(
            compression_m, velocity_world_m_s, legs, belly_up, hold_n, crouch=crouch
        )
    if nx == 0.0 and ny == 0.0:  # level: the leg axis is the ground normal
        return _level_stance_force(compression_m, vx, vy, vz, legs, crouch=crouch)
    v_n = vx * nx + vy * ny + vz * nz
    normal = leg_normal_force(compression_m, v_n, legs, crouch)
    if normal == 0.0:
        return 0.0, 0.0, 0.0
    tx, ty, tz = vx - v_n * nx, vy - v_n * ny, vz - v_n * nz  # across the leg axis
    speed_t = math.sqrt(tx * tx + ty * ty + tz * tz)
    fx, fy, fz = normal * nx, normal * ny, normal * nz
    if speed_t > 0.0:
        tangential = min(
            legs.tangential_damping_n_s_m * speed_t,
            math.sqrt(max(legs.force_max_n * legs.force_max_n - normal * normal, 0.0)),
        )
        scale = -tangential / speed_t
        fx, fy, fz = fx + scale * tx, fy + scale * ty, fz + scale * tz
    if fz <= 0.0:  # the feet cannot pull on the ground
        return 0.0, 0.0, 0.0
    along_ground = math.hypot(fx, fy)
    cone = legs.friction_coefficient * fz
    if along_ground > cone:  # the feet slip: the ground holds mu times the normal part
        cut = cone / along_ground
        fx, fy = fx * cut, fy * cut
    return fx, fy, fz


def _held_stance_force(
    compression_m: float,
    velocity: tuple[float, float, float],
    legs: LegImpedance,
    belly_up: tuple[float, float, float],
    hold_n: tuple[float, float],
    *,
    crouch: bool = False,
) -> tuple[float, float, float]:
    """:func:`leg_stance_force` with planted feet: the hold spring and damper along the
    ground, within the friction cone and the force cap (normal first)."""
    vx, vy, vz = velocity
    nx, ny, nz = belly_up
    v_n = vx * nx + vy * ny + vz * nz
    normal = leg_normal_force(compression_m, v_n, legs, crouch)
    if normal == 0.0:
        return 0.0, 0.0, 0.0
    fx, fy, fz = normal * nx, normal * ny, normal * nz
    if fz <= 0.0:
        return 0.0, 0.0, 0.0
    damping = max(legs.hold_damping_n_s_m, legs.tangential_damping_n_s_m)
    tx = hold_n[0] - damping * vx + fx
    ty = hold_n[1] - damping * vy + fy
    along = math.hypot(tx, ty)
    limit = min(
        legs.friction_coefficient * fz,
        math.sqrt(max(legs.force_max_n * legs.force_max_n - fz * fz, 0.0)),
    )
    if along > limit:
        tx, ty = tx * limit / along, ty * limit / along
    return tx, ty, fz


def foot_hold_force(offset_m: tuple[float, float], legs: LegImpedance) -> tuple[float, float]:
    """Spring force (x, y) [N] along the ground of feet planted ``offset_m`` behind the
    hemi: ``-k_hold offset`` (:attr:`LegImpedance.hold_stiffness_n_m`).

    The hip damper alone lets a hemi standing on a slope creep downhill at
    ``m g sin(slope) / c_t`` (0.13 m/s for a lunar hemi on 10 deg) and slows a slide
    with less than the ground's friction below ``mu N / c_t``; planted feet hold it
    where the friction cone allows and slip at its edge (:func:`slipped_anchor`).
    """
    k = legs.hold_stiffness_n_m
    return -k * offset_m[0], -k * offset_m[1]


def slipped_anchor(
    where_m: tuple[float, float],
    anchor_m: tuple[float, float],
    limit_n: float,
    legs: LegImpedance,
) -> tuple[float, float]:
    """Where planted feet stand after this step: unchanged while their spring pulls
    within ``limit_n`` [N] (the friction cone, and what the force cap leaves), else
    dragged behind the hemi at ``where_m`` so that it pulls exactly ``limit_n``.

    A bristle model of Coulomb friction: a sliding hemi is braked by the cone's edge,
    a hemi the cone can hold stops and stays (no creep).
    """
    dx, dy = where_m[0] - anchor_m[0], where_m[1] - anchor_m[1]
    stretch = math.hypot(dx, dy)
    reach = max(limit_n, 0.0) / legs.hold_stiffness_n_m
    if stretch <= reach:
        return anchor_m
    scale = reach / stretch
    return where_m[0] - scale * dx, where_m[1] - scale * dy


def _level_stance_force(
    compression_m: float,
    vx: float,
    vy: float,
    vz: float,
    legs: LegImpedance,
    *,
    crouch: bool = False,
) -> tuple[float, float, float]:
    """:func:`leg_stance_force` of a level hemi (the leg axis is the ground normal)."""
    normal = leg_normal_force(compression_m, vz, legs, crouch)
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


def roll_load_share(
    roll_sine: float,
    roll_rate_rad_s: float,
    load_n: float,
    lever_m: float,
    legs: LegImpedance,
) -> float:
    """Share ``u`` in [-1/2, 1/2] of a hemi's leg load moved from its right to its left feet.

    The left feet (body ``+y``, ``lever_m`` out) then carry ``(1/2 + u)`` of the load
    ``load_n`` [N] along the leg axis, the right feet ``(1/2 - u)``: a moment
    ``2 u lever load`` about body ``+x``, the levelling moment ``-k_roll roll_sine -
    c_roll roll_rate`` as far as the support polygon allows (module docstring).
    ``roll_sine`` is the world ``z`` of body ``+y`` (sine of the roll about the
    tether), ``roll_rate_rad_s`` the body rate about ``x``.
    """
    if load_n <= 0.0 or lever_m <= 0.0:
        return 0.0
    moment = -legs.roll_stiffness_nm_rad * roll_sine - legs.roll_damping_nm_s_rad * roll_rate_rad_s
    return min(max(moment / (2.0 * lever_m * load_n), -0.5), 0.5)
