"""Gait phase machine: the paper's Launch, In-Flight, Jump and Landing phases, plus LANDED.

ROS-free and deterministic: :class:`GaitPhaseMachine` is a pure state machine fed
once per control tick with the measured state and the ground contact forces; it
returns the gait phase, the jump wrench about the centre of mass and, when it
changes, the attitude reference for the MPC. The ``gait_phase_manager`` node and
the library closed loop call the same object in the same order.

Phases (paper section III.A; names from ``splitter_msgs_py.names.GAIT_PHASES``), a
state machine on debounced contact events::

    LAUNCH --lift-off--> IN_FLIGHT --touchdown, a jump left--> JUMP --lift-off--> IN_FLIGHT
       |                    |                                    |
       |                    +-- descending after the last jump --+--> LANDING --at rest--> LANDED
       +-- (a jump that never leaves the ground) ------------------------^       (final)

:data:`ALLOWED_TRANSITIONS` lists every change the machine can make; anything else
is an error. Each change is reported once, on its tick, with its reason
(:attr:`GaitOutput.reason`).

* Contact events. A hemi is in stance when its ground normal force (legs, jump
  thrust and lumped masses together) is above ``stance_force_threshold_n``.
  Touchdown: some hemi in stance without a break for ``touchdown_debounce_s``.
  Lift-off: no hemi in stance for longer than ``liftoff_debounce_s``. A phase
  therefore never changes on a contact flicker shorter than the debounce. On the
  first tick the measured stance is taken as it is.
* First phase: on the ground with a jump planned LAUNCH, on the ground without
  one LANDING, in the air IN_FLIGHT.
* Jumps (``LAUNCH`` and ``JUMP`` are the ground phases): a thrust starts at the
  first tick at or after the jump's planned time, in a ground phase, when the
  pushing hemi is in stance (``"a"``, ``"b"``, or ``"auto"``: the hemis in stance
  share the force). It lasts the planned duration or until lift-off, whichever
  comes first (the simulator also ends it when the legs leave their stroke).
  A due jump whose hemi is not in stance waits (:attr:`GaitOutput.jump_waiting`).
  A touchdown with a jump left is JUMP (paper: "one Hemi-SPLITTER makes contact
  with the ground and jumps"): the robot stands until the jump is due and it has
  settled: the touchdown absorbed (the COM's vertical speed below
  ``jump_settle_speed_m_s``) and the spin stopped by the feet's friction (``|w|``
  below ``jump_settle_angular_speed_rad_s``); the forward speed is carried (a
  running hop). A push from legs still in their landing stroke, or from a robot
  still turning, would launch the next flight with the landing's speed and spin in
  it.
* Downhill jumps. A standing robot's belly axis (body z, from the measured attitude)
  is the ground's normal. A jump that heads downhill a plane steeper than
  ``jump_level_slope_deg`` falls further than it rose and meets the ground faster
  than it left; its push is scaled (:func:`downhill_speed_scale`,
  :func:`scaled_jump`) so that it meets the plane no faster than on level ground,
  the speed the legs' stroke is sized for. The forward speed a running hop carries
  is not counted.
* Landing (paper: "towards Landing, SPLITTER de-thrusts the system, and the
  attitude controller slows down the angular velocity"): once every planned jump
  is done and the centre of mass descends, the phase is LANDING; the attitude
  reference then asks for ``landing_w_ref_rad_s`` (zero by default: slow the
  spin). No thrust is commanded any more; the simulator's compliant legs absorb
  the touchdown. A run with no jump planned is IN_FLIGHT until its first
  touchdown, then LANDING.
* LANDED: both hemis in stance, the robot on the ground, speed below
  ``landed_speed_m_s`` and ``|w|`` below ``landed_angular_speed_rad_s`` without a
  break for ``landed_dwell_s`` (DESIGN.md: 1 s). It is final.

Attitude reference (``AttitudeReference``): emitted on the first tick and when
Landing starts, made by :func:`attitude_reference_at_stamp` from the state
measured on that tick. In mode ``"integrate_w_ref"`` the attitude reference starts
at the measured attitude and is propagated by the consumer with the angular
velocity reference (``q_ref(t) = q_ref(t0) (x) exp(w_ref (t - t0) / 2)``,
body-frame rate); in mode ``"initial"`` the measured attitude is held. Mode
``"momentum_aligned"`` propagates the same way from a reachable start,
``q_align (x) q(t0)`` (:func:`momentum_aligned_attitude`): in torque-free flight
the world angular momentum H is conserved, so a steady spin about the body axis
``e = w_ref / |w_ref|`` has e along H; ``q_align`` is the smallest rotation that
puts the measured body e there. What is left to track is then the phase of the
spin about H (which the morphing sets through ``e' I e``).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from enum import StrEnum
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.model import RobotModel
from splitter_model.rotations import quaternion_multiply
from splitter_model.rotations import quaternion_to_matrix as rotation_matrix
from splitter_msgs_py import names
from splitter_msgs_py.core.parameter_fields import parameter_field, parameter_fields

_LOG = logging.getLogger(__name__)

NS_PER_S = 1_000_000_000  # [ns/s]
HEMI_INDEX: dict[str, int] = {hemi: i for i, hemi in enumerate(names.HEMIS)}
JUMP_HEMIS = ("a", "b", "auto", "both")
ATTITUDE_REFERENCE_MODES = ("initial", "integrate_w_ref", "momentum_aligned", "landing_timed")
LANDING_SPIN_AXIS = (0.0, 0.0, 1.0)  # body z, the belly normal: the spin a landing keeps
# [deg] a momentum this close to the vertical tilts the tether at most this much at any
# phase: 5.6 m x sin 3 deg = 0.29 m between the hemis, within the legs' 0.4 m stroke, so
# the landing is not timed (timing it costs spin)
LANDING_TILT_TOLERANCE_DEG = 3.0
# [rad/s] a timed landing may slow the spin at will but spin it up no faster than this:
# lunar_jumping's launch spin (0.46 rad/s), which the legs are shown to land. Reeling in
# to advance the phase of a slow spin (a second flight's 0.1 rad/s) otherwise asks for
# 1 rad/s and more, and the reel-in pumps the nutation of a momentum off the belly.
LANDING_RATE_MAX_RAD_S = 0.5
AXIS_EPS_RAD_S = 1e-9  # [rad/s] a w_ref shorter than this has no axis (as in the MPC's OCP)
MOMENTUM_EPS_KG_M2_S = 1e-9  # [kg m^2/s] an angular momentum shorter than this has no direction
# [-] |a + b| of unit vectors below which they count as opposite: sqrt(float64 eps), the
# tolerance that bounds both branches of smallest_rotation's error (~2e-8 rad).
ANTIPARALLEL_TOLERANCE = 1.5e-8


class GaitPhase(StrEnum):
    """The gait phases, valued as published on ``/splitter/gait_phase``."""

    LAUNCH = "LAUNCH"
    IN_FLIGHT = "IN_FLIGHT"
    JUMP = "JUMP"
    LANDING = "LANDING"
    LANDED = "LANDED"


def seconds_to_ns(t_s: float) -> int:
    """Integer nanoseconds of a time in seconds, rounded to the nearest ns."""
    return round(t_s * NS_PER_S)


# --- input checks --------------------------------------------------------------------------
def _vector3(value: ArrayLike, name: str) -> NDArray[np.float64]:
    arr = np.asarray(value, dtype=float).reshape(-1)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: expected 3 finite numbers, got {value!r}")
    return arr


def _principal_inertia(value: ArrayLike, name: str) -> NDArray[np.float64]:
    """``value`` as 3 finite, positive principal moments [kg m^2]; ``ValueError`` if not."""
    inertia = _vector3(value, name)
    if np.any(inertia <= 0.0):
        raise ValueError(f"{name}: moments must be > 0, got {inertia.tolist()}")
    return inertia


def _quaternion(value: ArrayLike, name: str) -> NDArray[np.float64]:
    """``value`` as a unit quaternion; ``ValueError`` when it is not finite and non-zero."""
    q = np.asarray(value, dtype=float).reshape(-1)
    if q.shape != (4,) or not np.all(np.isfinite(q)) or np.linalg.norm(q) == 0.0:
        raise ValueError(f"{name}: expected a finite quaternion, got {q.tolist()}")
    return q / np.linalg.norm(q)


# --- quaternions (scalar first, world <- base) -------------------------------------------
def propagate_attitude(
    q_wxyz: ArrayLike, angular_velocity_rad_s: ArrayLike, dt_s: float
) -> NDArray[np.float64]:
    """Attitude after ``dt_s`` at a constant body-frame rate: ``q (x) exp(w dt / 2)``."""
    w = np.asarray(angular_velocity_rad_s, dtype=float)
    angle = float(np.linalg.norm(w)) * dt_s  # [rad]
    if angle == 0.0:
        delta = np.array([1.0, 0.0, 0.0, 0.0])
    else:
        axis = w / np.linalg.norm(w)
        delta = np.concatenate(([math.cos(angle / 2.0)], math.sin(angle / 2.0) * axis))
    q = quaternion_multiply(q_wxyz, delta)
    return q / np.linalg.norm(q)


def _unit3(value: ArrayLike, name: str) -> NDArray[np.float64]:
    v = _vector3(value, name)
    norm = float(np.linalg.norm(v))
    if abs(norm - 1.0) > 1e-9:
        raise ValueError(f"{name}: expected a unit vector, got |v| = {norm}")
    return v / norm


def smallest_rotation(
    from_unit: ArrayLike, to_unit: ArrayLike, half_turn_axis: ArrayLike
) -> NDArray[np.float64]:
    """Unit quaternion (w, x, y, z) of the smallest rotation taking unit ``a`` onto unit ``b``.

    Angle ``acos(a . b)`` about ``a x b``. With the half-way vector
    ``h = (a + b) / |a + b|`` it is ``(a . h, a x h)``, unit by construction and
    accurate to ~1e-16 / |a + b| rad. When ``b = -a`` (``|a + b|`` below
    :data:`ANTIPARALLEL_TOLERANCE`) every axis perpendicular to ``a`` gives a half
    turn of the same size: the part of ``half_turn_axis`` perpendicular to ``a`` is
    used (it must not be parallel to ``a``). ``ValueError`` for non-unit inputs.
    """
    a = _unit3(from_unit, "from_unit")
    b = _unit3(to_unit, "to_unit")
    halfway = a + b
    length = float(np.linalg.norm(halfway))
    if length >= ANTIPARALLEL_TOLERANCE:
        h = halfway / length
        return np.concatenate(([float(a @ h)], np.cross(a, h)))
    hint = _vector3(half_turn_axis, "half_turn_axis")
    axis = hint - a * float(a @ hint)
    norm = float(np.linalg.norm(axis))
    if norm < 1e-6 * max(float(np.linalg.norm(hint)), 1e-300):
        raise ValueError(f"half_turn_axis: {hint.tolist()} is parallel to from_unit {a.tolist()}")
    return np.concatenate(([0.0], axis / norm))


def momentum_aligned_attitude(
    orientation_wxyz: ArrayLike,
    angular_velocity_rad_s: ArrayLike,
    principal_inertia_kg_m2: ArrayLike,
    w_ref_rad_s: ArrayLike,
) -> NDArray[np.float64]:
    """``q_align (x) q``: the attitude ``q`` turned so that body ``e = w_ref / |w_ref|`` is along H.

    ``H = R(q) I w`` is the world angular momentum [kg m^2/s] of the body rate
    ``w`` [rad/s] with the principal moments ``I = (Ixx, Iyy, Izz)`` [kg m^2]
    (paper eq. 2; world <- base, scalar first). Conserved in torque-free flight,
    it is the only direction a steady spin about e can have; ``+H`` (not ``-H``)
    keeps the sense of ``w_ref``: a positive spin about e has its body momentum
    along ``+e``. ``q_align`` is the smallest world-frame rotation taking
    ``R(q) e`` onto ``H / |H|`` (:func:`smallest_rotation`); when they are opposite,
    it is the half turn about the world direction of the body axis most
    perpendicular to e (the first of x, y, z in a tie; body x for e = y, the axis
    a nearly axisymmetric SPLITTER turns about).

    Degenerate cases return ``q`` as given (the unaligned reference):
    ``|w_ref|`` below :data:`AXIS_EPS_RAD_S` (no axis) or ``|H|`` below
    :data:`MOMENTUM_EPS_KG_M2_S` (no direction). ``ValueError`` names a
    non-finite or malformed input or a non-positive moment.
    """
    given = np.asarray(orientation_wxyz, dtype=float).reshape(-1)
    q = _quaternion(given, "orientation_wxyz")
    w = _vector3(angular_velocity_rad_s, "angular_velocity_rad_s")
    inertia = _principal_inertia(principal_inertia_kg_m2, "principal_inertia_kg_m2")
    w_ref = _vector3(w_ref_rad_s, "w_ref_rad_s")
    speed = float(np.linalg.norm(w_ref))  # [rad/s]
    rotation = rotation_matrix(q)
    momentum_world = rotation @ (inertia * w)  # H [kg m^2/s]
    momentum_norm = float(np.linalg.norm(momentum_world))
    if speed < AXIS_EPS_RAD_S or momentum_norm < MOMENTUM_EPS_KG_M2_S:
        _LOG.debug(
            "momentum_aligned: |w_ref| = %g rad/s, |H| = %g kg m^2/s: no axis to align, "
            "the measured attitude is the reference",
            speed,
            momentum_norm,
        )
        return given.copy()
    axis_body = w_ref / speed  # e
    perpendicular = int(np.argmin(np.abs(axis_body)))
    q_align = smallest_rotation(
        rotation @ axis_body, momentum_world / momentum_norm, rotation[:, perpendicular]
    )
    aligned = quaternion_multiply(q_align, q)
    return aligned / np.linalg.norm(aligned)


def attitude_reference_at_stamp(
    mode: str,
    orientation_wxyz: ArrayLike,
    angular_velocity_rad_s: ArrayLike,
    principal_inertia_kg_m2: ArrayLike | None,
    w_ref_rad_s: ArrayLike,
) -> tuple[NDArray[np.float64], bool]:
    """(attitude reference at its stamp, propagated with ``w_ref``?) from the state measured then.

    ``mode`` is one of :data:`ATTITUDE_REFERENCE_MODES` (module docstring). The gait
    machine makes its references here and the flight metrics rebuild them here,
    so the error is measured against the reference the MPC was given.
    ``principal_inertia_kg_m2`` [kg m^2] is needed by ``"momentum_aligned"`` only.
    """
    if mode not in ATTITUDE_REFERENCE_MODES:
        raise ValueError(
            f"attitude_reference: must be one of {ATTITUDE_REFERENCE_MODES}, got {mode!r}"
        )
    if mode == "momentum_aligned":
        if principal_inertia_kg_m2 is None:
            raise ValueError(
                "principal_inertia_kg_m2: needed by attitude_reference 'momentum_aligned'"
            )
        q = momentum_aligned_attitude(
            orientation_wxyz, angular_velocity_rad_s, principal_inertia_kg_m2, w_ref_rad_s
        )
        return q, True
    given = np.asarray(orientation_wxyz, dtype=float).reshape(-1)
    _quaternion(given, "orientation_wxyz")
    return given.copy(), mode in ("integrate_w_ref", "landing_timed")


def timed_landing_reference(
    orientation_wxyz: ArrayLike,
    angular_velocity_rad_s: ArrayLike,
    principal_inertia_kg_m2: ArrayLike,
    touchdown_in_s: float,
    *,
    spin_axis_body: ArrayLike = LANDING_SPIN_AXIS,
    tilt_tolerance_deg: float = LANDING_TILT_TOLERANCE_DEG,
    rate_max_rad_s: float = LANDING_RATE_MAX_RAD_S,
) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """(attitude reference now, body rate reference) that meets the ground with the tether level.

    In torque-free flight the world angular momentum ``H = R I w`` is conserved; a
    steady spin about the body axis ``e`` (the belly normal, the axis the morphing
    makes the largest moment in flight) has ``e`` along ``H`` and the tether (body x)
    turning in the plane across ``H``, level twice a turn: along ``u = H x z_world``.
    The reference starts from the momentum-aligned attitude
    (:func:`momentum_aligned_attitude`), whose tether is ``phi0`` from ``u`` about
    ``H``, and spins about ``e`` at the rate ``w*`` that turns the tether onto ``+-u``
    in ``touchdown_in_s`` [s]: ``w* = (k pi - phi0) / T``, the ``k`` whose ``w*`` is
    nearest the spin the momentum has about ``e`` now (``|H| / e' I e``; the tether
    length sets it, so the MPC needs the least morphing) and no faster than
    ``max(rate_max_rad_s, that spin)``. None when there is nothing to time: no
    momentum, no time left, ``H`` within ``tilt_tolerance_deg`` of the vertical (the
    tether is then as level at every phase), the spin it has would meet the ground
    with the tether within that tolerance anyway (timing costs spin), or only a faster
    spin than that would time it.
    """
    geometry = _landing_geometry(
        orientation_wxyz,
        angular_velocity_rad_s,
        principal_inertia_kg_m2,
        touchdown_in_s,
        spin_axis_body,
        tilt_tolerance_deg,
    )
    if geometry is None:
        return None
    aligned, axis, phi0, rate_now = geometry
    k = round((rate_now * touchdown_in_s + phi0) / math.pi)
    candidates = [(j * math.pi - phi0) / touchdown_in_s for j in (k - 1, k, k + 1)]
    fastest = max(rate_max_rad_s, rate_now)
    allowed = [c for c in candidates if 0.0 < c <= fastest]
    if not allowed:
        return None
    rate = min(allowed, key=lambda c: (abs(c - rate_now), c))
    return aligned, axis * rate


@dataclass(frozen=True)
class LandingTiming:
    """A timed landing in two steady spins about the belly: ``spin_up_s`` [s] at
    ``spin_up_rad_s`` from the lift-off, then ``landing_rate_rad_s`` to the touchdown.

    ``spin_up_s`` is 0 when one steady spin times the landing.
    """

    attitude_wxyz: NDArray[np.float64]  # the reference at the lift-off (world <- base)
    spin_axis_body: NDArray[np.float64]  # [-] unit, the belly
    spin_up_rad_s: float  # [rad/s] the first spin
    spin_up_s: float  # [s] how long it lasts
    landing_rate_rad_s: float  # [rad/s] the spin that meets the ground

    def switch(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(attitude reference, body rate reference) when the spin-up ends."""
        first = self.spin_axis_body * self.spin_up_rad_s
        return (
            propagate_attitude(self.attitude_wxyz, first, self.spin_up_s),
            self.spin_axis_body * self.landing_rate_rad_s,
        )


def timed_landing_plan(
    orientation_wxyz: ArrayLike,
    angular_velocity_rad_s: ArrayLike,
    principal_inertia_kg_m2: ArrayLike,
    touchdown_in_s: float,
    *,
    slowest_fraction: float,
    spin_up_rad_s: float,
    settle_s: float,
    spin_axis_body: ArrayLike = LANDING_SPIN_AXIS,
    tilt_tolerance_deg: float = LANDING_TILT_TOLERANCE_DEG,
    rate_max_rad_s: float = LANDING_RATE_MAX_RAD_S,
) -> LandingTiming | None:
    """A timed landing with the reach of a spin-up: :func:`timed_landing_reference`'s
    goal (the tether level at the touchdown) where one steady spin cannot reach it.

    A steady spin ``w*`` times the landing only between the slowest spin the reel can
    pay out to (``slowest_fraction`` of the spin now: the moment about the belly now
    over the largest the reel reaches) and ``max(rate_max_rad_s, spin now)``: for
    lunar_jumping's launch 0.40-0.5 rad/s, -0.26 to +0.18 rad over a 4.4 s flight,
    where a level touchdown may need up to +-pi/2. Reeling in first advances the
    phase: ``tau`` s at ``spin_up_rad_s``, then the landing spin ``w_L = min(spin now,
    rate_max_rad_s)`` for the rest, so ``tau (w_up - w_L) + w_L T``
    turns the tether onto a level direction (``k pi - phi0``), with at least
    ``settle_s`` [s] left to reel back out before the touchdown. Choice: the steady
    spin within reach nearest the spin now, else the shortest spin-up; where neither
    reaches, the reachable plan nearest level (the slowest or fastest steady spin, or
    the longest spin-up) if it is nearer than the spin the robot has. None when there
    is nothing to time (as :func:`timed_landing_reference`) or nothing nearer.
    """
    if not (math.isfinite(slowest_fraction) and 0.0 < slowest_fraction <= 1.0):
        raise ValueError(f"slowest_fraction: must be in (0, 1], got {slowest_fraction}")
    for name, value in (("spin_up_rad_s", spin_up_rad_s), ("settle_s", settle_s)):
        if not (math.isfinite(value) and value >= 0.0):
            raise ValueError(f"{name}: must be finite and >= 0, got {value}")
    geometry = _landing_geometry(
        orientation_wxyz,
        angular_velocity_rad_s,
        principal_inertia_kg_m2,
        touchdown_in_s,
        spin_axis_body,
        tilt_tolerance_deg,
    )
    if geometry is None:
        return None
    aligned, axis, phi0, rate_now = geometry
    total = touchdown_in_s
    fastest = max(rate_max_rad_s, rate_now)
    slowest = slowest_fraction * rate_now
    landing_rate = min(rate_now, rate_max_rad_s)
    k = round((rate_now * total + phi0) / math.pi)
    targets = [j * math.pi - phi0 for j in range(k - 2, k + 4)]  # [rad] turns that level it
    steady = [theta / total for theta in targets if slowest <= theta / total <= fastest]
    if steady:
        rate = min(steady, key=lambda c: (abs(c - rate_now), c))
        return LandingTiming(aligned, axis, rate, 0.0, rate)
    gain = spin_up_rad_s - landing_rate  # [rad/s] phase gained per second of spin-up
    longest = total - settle_s  # [s] the longest spin-up
    if gain > 0.0:
        spin_ups = [
            tau
            for tau in ((theta - landing_rate * total) / gain for theta in targets)
            if 0.0 < tau <= longest
        ]
        if spin_ups:
            return LandingTiming(aligned, axis, spin_up_rad_s, min(spin_ups), landing_rate)

    def miss(turn: float) -> float:  # [rad] of the tether's phase from level at touchdown
        return abs(math.remainder(turn + phi0, math.pi))

    # Out of reach: the reachable plan that meets the ground nearest level, if nearer
    # than the spin it has (the tether's tilt grows with the phase missed).
    nearest = [
        (slowest * total, LandingTiming(aligned, axis, slowest, 0.0, slowest)),
        (fastest * total, LandingTiming(aligned, axis, fastest, 0.0, fastest)),
    ]
    if gain > 0.0 and longest > 0.0:
        nearest.append(
            (
                landing_rate * total + gain * longest,
                LandingTiming(aligned, axis, spin_up_rad_s, longest, landing_rate),
            )
        )
    turn, best = min(nearest, key=lambda option: miss(option[0]))
    return best if miss(turn) < miss(rate_now * total) else None


def _landing_geometry(  # noqa: PLR0917 (timed_landing_reference's own inputs)
    orientation_wxyz: ArrayLike,
    angular_velocity_rad_s: ArrayLike,
    principal_inertia_kg_m2: ArrayLike,
    touchdown_in_s: float,
    spin_axis_body: ArrayLike,
    tilt_tolerance_deg: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float] | None:
    """(momentum-aligned attitude, belly axis, tether phase from level phi0 [rad], spin
    about the belly [rad/s]) of a landing worth timing, else None."""
    q = _quaternion(orientation_wxyz, "orientation_wxyz")
    w = _vector3(angular_velocity_rad_s, "angular_velocity_rad_s")
    inertia = _principal_inertia(principal_inertia_kg_m2, "principal_inertia_kg_m2")
    axis = _unit3(spin_axis_body, "spin_axis_body")
    momentum = rotation_matrix(q) @ (inertia * w)  # H [kg m^2/s]
    momentum_norm = float(np.linalg.norm(momentum))
    if not (math.isfinite(touchdown_in_s) and touchdown_in_s > 0.0):
        return None
    if momentum_norm < MOMENTUM_EPS_KG_M2_S:
        return None
    h = momentum / momentum_norm
    level = np.cross(h, (0.0, 0.0, 1.0))
    if float(np.linalg.norm(level)) < math.sin(math.radians(tilt_tolerance_deg)):
        return None
    level /= np.linalg.norm(level)
    aligned = momentum_aligned_attitude(q, w, inertia, axis)
    tether = rotation_matrix(aligned)[:, 0]
    phi0 = math.atan2(float(np.cross(level, tether) @ h), float(level @ tether))
    rate_now = momentum_norm / float(axis**2 @ inertia)  # [rad/s] about e
    # left alone, the spin it has meets the ground with the tether this far from level
    coasting = rotation_matrix(propagate_attitude(aligned, axis * rate_now, touchdown_in_s))
    if abs(float(coasting[2, 0])) < math.sin(math.radians(tilt_tolerance_deg)):
        return None
    return aligned, axis, phi0, rate_now


# --- geometry ------------------------------------------------------------------------------
def hemi_offset_world(
    orientation_wxyz: ArrayLike, radius_x_m: float, hemi: str
) -> NDArray[np.float64]:
    """``p_hemi - p_com`` in world: ``R(q) (s r_x, 0, 0)``, s = +1 for hemi a, -1 for b."""
    sign = names.HEMI_SIGNS[hemi]
    return rotation_matrix(orientation_wxyz)[:, 0] * (sign * radius_x_m)


def jump_wrench(
    force_n: ArrayLike, orientation_wxyz: ArrayLike, radius_x_m: float, hemi: str
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Force [N] and torque about the centre of mass [Nm] (world) of a thrust through ``hemi``.

    The pushing legs act on the hemi body, so the torque is
    ``(p_hemi - p_com) x F``.
    """
    force = np.asarray(force_n, dtype=float)
    return force.copy(), np.cross(hemi_offset_world(orientation_wxyz, radius_x_m, hemi), force)


def predicted_touchdown_s(
    height_m: float, vertical_speed_m_s: float, gravity_m_s2: float, touchdown_height_m: float
) -> float:
    """Time [s] until a body at ``height_m`` rising at ``vertical_speed_m_s`` falls to
    ``touchdown_height_m`` under ``gravity_m_s2`` (ballistic); 0 at or below it, inf if
    it never gets there (no gravity and not descending).

    The later root of ``h + v t - g t^2 / 2 = h_td``:
    ``t = (v + sqrt(v^2 + 2 g (h - h_td))) / g``.
    """
    above = height_m - touchdown_height_m
    if above <= 0.0:
        return 0.0
    v, g = vertical_speed_m_s, gravity_m_s2
    if g == 0.0:
        return above / -v if v < 0.0 else math.inf
    return (v + math.sqrt(v * v + 2.0 * g * above)) / g


def downhill_speed_scale(
    force_n: ArrayLike,
    ground_normal: ArrayLike,
    mass_kg: float,
    gravity_m_s2: float,
    level_slope_deg: float = 0.0,
) -> float:
    """The factor (0, 1] on a push's lift-off speed that meets a downhill plane no faster
    than the same push meets level ground.

    A push of ``force_n`` [N] (world, the whole thrust) on ``mass_kg`` [kg] from rest
    launches along ``a = F / m - g z``. Over a plane through the start with upward unit
    normal ``n``, a ballistic flight leaving at ``v`` is above it until
    ``t = 2 (n . v) / (g n_z)``, where its vertical speed is ``v_z - 2 (n . v) / n_z``:
    ``-v_z`` on level ground, ``k = 1 + 2 (n_h . v_h) / (n_z v_z)`` times that when the
    push heads downhill (``n_h``, ``v_h`` the horizontal parts). The factor is ``1 / k``
    there and 1 otherwise (uphill, across, a push that does not lift, or a slope below
    ``level_slope_deg`` [deg]). The legs stop a touchdown within their stroke only up
    to a speed (:func:`splitter_sim.core.legs.stroke_left_after_stop_m`); a 6 deg slope
    down a 10 m hop adds 1 m of fall, 0.3-0.4 m/s at the nominal 3.6 m/s.
    """
    normal = _unit3(ground_normal, "ground_normal")
    if not (math.isfinite(mass_kg) and mass_kg > 0.0):
        raise ValueError(f"mass_kg: must be finite and > 0, got {mass_kg}")
    if not (math.isfinite(gravity_m_s2) and gravity_m_s2 >= 0.0):
        raise ValueError(f"gravity_m_s2: must be finite and >= 0, got {gravity_m_s2}")
    launch = _vector3(force_n, "force_n") / mass_kg - np.array([0.0, 0.0, gravity_m_s2])
    slope_deg = math.degrees(math.acos(min(1.0, abs(float(normal[2])))))
    if gravity_m_s2 == 0.0 or normal[2] <= 0.0 or launch[2] <= 0.0 or slope_deg < level_slope_deg:
        return 1.0
    downhill = float(normal[0] * launch[0] + normal[1] * launch[1])  # n_h . v_h, same scale
    ratio = 1.0 + 2.0 * downhill / (float(normal[2]) * float(launch[2]))
    return 1.0 / ratio if ratio > 1.0 else 1.0


def scaled_jump(jump: PlannedJump, speed_scale: float, weight_n: float) -> PlannedJump:
    """``jump`` with its lift-off speed scaled by ``speed_scale`` (direction kept).

    A push over the legs' stroke from rest leaves at ``|v| = sqrt(2 |a| d)`` along
    ``a = (F - W) / m``, so the speed scales by ``s`` when the force above the weight
    ``W`` (``weight_n`` [N], the whole robot's, along world z) scales by ``s^2``: each
    hemi's force becomes ``W_h + s^2 (F_h - W_h)`` with ``W_h`` its share of the weight
    (half each for "both"). The couple across the tether is kept.
    """
    if speed_scale == 1.0:
        return jump
    factor = speed_scale * speed_scale

    def scale(force: tuple[float, float, float], share: float) -> tuple[float, float, float]:
        w = weight_n * share
        return (factor * force[0], factor * force[1], w + factor * (force[2] - w))

    if jump.hemi == "both":
        return replace(jump, force_n=scale(jump.force_n, 0.5), force_b_n=scale(jump.force_b_n, 0.5))
    return replace(jump, force_n=scale(jump.force_n, 1.0))


# --- the jump plan -------------------------------------------------------------------------
class JumpLike(Protocol):
    """Anything shaped like ``splitter_bringup.scenario.definition.JumpSpec``."""

    time_s: float
    force_n: Sequence[float]
    duration_s: float
    hemi: str
    force_b_n: Sequence[float]
    couple_n: float


@dataclass(frozen=True)
class PlannedJump:
    """One planned jump on the integer-nanosecond clock.

    ``hemi`` "both": the two hemis push at once, hemi a ``force_n`` and hemi b
    ``force_b_n`` (a launch that adds rotation); otherwise ``force_n`` is the whole
    thrust and ``force_b_n`` is zero. ``couple_n`` [N] (hemi "both" or "auto"): each
    hemi also pushes this much across the tether in the horizontal plane, in opposite
    directions, hemi a towards ``z x t`` (``t`` the tether's horizontal direction from
    hemi b to a): a couple of ``2 r_x couple_n`` about the vertical, counter-clockwise
    seen from above for a positive one, whatever the robot's heading. A launch states
    its spin in world forces (it starts from a known heading); a later jump, from
    wherever the last landing turned the robot, states it with this.
    """

    time_ns: int  # [ns] earliest start
    force_n: tuple[float, float, float]  # [N] world frame (hemi a's when "both")
    duration_ns: int  # [ns]
    hemi: str  # "a", "b", "auto" or "both"
    force_b_n: tuple[float, float, float] = (0.0, 0.0, 0.0)  # [N] world, hemi b's ("both")
    couple_n: float = 0.0  # [N] each hemi's push across the tether (a spin about the vertical)

    @classmethod
    def from_spec(cls, spec: JumpLike) -> PlannedJump:
        """From a scenario ``JumpSpec`` (or anything with the same fields)."""
        force = tuple(float(f) for f in spec.force_n)
        force_b = tuple(float(f) for f in getattr(spec, "force_b_n", (0.0, 0.0, 0.0)))
        return cls(
            time_ns=seconds_to_ns(float(spec.time_s)),
            force_n=(force[0], force[1], force[2]),
            duration_ns=seconds_to_ns(float(spec.duration_s)),
            hemi=str(spec.hemi),
            force_b_n=(force_b[0], force_b[1], force_b[2]),
            couple_n=float(getattr(spec, "couple_n", 0.0)),
        )

    @property
    def total_force_n(self) -> tuple[float, float, float]:
        """The whole thrust [N] (both hemis' when "both")."""
        a, b = self.force_n, self.force_b_n
        return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def validate_jump_plan(jumps: Sequence[PlannedJump]) -> tuple[PlannedJump, ...]:
    """The plan, checked; ``ValueError`` names the offending jump and field.

    Times must be >= 0 and each planned thrust must end before the next jump's
    planned time (a later jump never interrupts an earlier one).
    """
    for i, jump in enumerate(jumps):
        where = f"jump {i}"
        if jump.time_ns < 0:
            raise ValueError(f"{where}: time_s must be >= 0, got {jump.time_ns / NS_PER_S}")
        if jump.duration_ns <= 0:
            raise ValueError(f"{where}: duration_s must be > 0, got {jump.duration_ns / NS_PER_S}")
        if len(jump.force_n) != 3 or not all(math.isfinite(f) for f in jump.force_n):
            raise ValueError(f"{where}: force_n must be 3 finite numbers, got {jump.force_n}")
        if len(jump.force_b_n) != 3 or not all(math.isfinite(f) for f in jump.force_b_n):
            raise ValueError(f"{where}: force_b_n must be 3 finite numbers, got {jump.force_b_n}")
        if jump.hemi != "both" and any(jump.force_b_n):
            raise ValueError(f"{where}: force_b_n is for hemi 'both' only, got hemi {jump.hemi!r}")
        if jump.hemi not in JUMP_HEMIS:
            raise ValueError(f"{where}: hemi must be one of {JUMP_HEMIS}, got {jump.hemi!r}")
        if not math.isfinite(jump.couple_n):
            raise ValueError(f"{where}: couple_n must be finite, got {jump.couple_n}")
        if jump.couple_n != 0.0 and jump.hemi not in ("both", "auto"):
            raise ValueError(
                f"{where}: couple_n needs both hemis (hemi 'both' or 'auto'), "
                f"got hemi {jump.hemi!r}"
            )
        if i > 0:
            previous = jumps[i - 1]
            if jump.time_ns < previous.time_ns + previous.duration_ns:
                raise ValueError(
                    f"{where}: time_s {jump.time_ns / NS_PER_S} s is before the end of jump "
                    f"{i - 1} ({(previous.time_ns + previous.duration_ns) / NS_PER_S} s)"
                )
    return tuple(jumps)


def jump_plan_from_arrays(
    times_s: Sequence[float],
    forces_n: Sequence[float],
    durations_s: Sequence[float],
    hemis: Sequence[str],
    forces_b_n: Sequence[float] = (),
    *,
    couples_n: Sequence[float] = (),
) -> tuple[PlannedJump, ...]:
    """The plan from flat parameter arrays (3 force components per jump), validated.

    ``forces_b_n``: hemi b's force of each jump (3 per jump; for hemi "both"), or
    empty (none); ``couples_n``: each jump's ``couple_n`` (one per jump), or empty
    (none). ``ValueError`` names the parameter (``jump_forces_n``, ...) that does not
    fit.
    """
    n = len(times_s)
    if len(couples_n) == 0:
        couples_n = [0.0] * n
    if len(couples_n) != n:
        raise ValueError(
            f"jump_couples_n: expected {n} values (one per jump) or none, got {len(couples_n)}"
        )
    if len(forces_b_n) == 0:
        forces_b_n = [0.0] * (3 * n)
    if len(forces_b_n) != 3 * n:
        raise ValueError(
            f"jump_forces_b_n: expected 3 values per jump ({3 * n}) or none, got {len(forces_b_n)}"
        )
    if len(forces_n) != 3 * n:
        raise ValueError(
            f"jump_forces_n: expected 3 values per jump ({3 * n}), got {len(forces_n)}"
        )
    if len(durations_s) != n:
        raise ValueError(
            f"jump_durations_s: expected {n} values (one per jump), got {len(durations_s)}"
        )
    if len(hemis) != n:
        raise ValueError(f"jump_hemis: expected {n} values (one per jump), got {len(hemis)}")
    for name, values in (
        ("jump_times_s", times_s),
        ("jump_forces_n", forces_n),
        ("jump_forces_b_n", forces_b_n),
        ("jump_durations_s", durations_s),
        ("jump_couples_n", couples_n),
    ):
        if not all(math.isfinite(float(v)) for v in values):
            raise ValueError(f"{name}: values must be finite, got {list(values)}")
    for i, hemi in enumerate(hemis):
        if hemi not in JUMP_HEMIS:
            raise ValueError(f"jump_hemis: entry {i} must be one of {JUMP_HEMIS}, got {hemi!r}")
    for i in range(n):
        if times_s[i] < 0.0:
            raise ValueError(f"jump_times_s: entry {i} must be >= 0, got {times_s[i]}")
        if durations_s[i] <= 0.0:
            raise ValueError(f"jump_durations_s: entry {i} must be > 0, got {durations_s[i]}")
    jumps = [
        PlannedJump(
            time_ns=seconds_to_ns(float(times_s[i])),
            force_n=(
                float(forces_n[3 * i]),
                float(forces_n[3 * i + 1]),
                float(forces_n[3 * i + 2]),
            ),
            duration_ns=seconds_to_ns(float(durations_s[i])),
            hemi=str(hemis[i]),
            force_b_n=(
                float(forces_b_n[3 * i]),
                float(forces_b_n[3 * i + 1]),
                float(forces_b_n[3 * i + 2]),
            ),
            couple_n=float(couples_n[i]),
        )
        for i in range(n)
    ]
    try:
        return validate_jump_plan(jumps)
    except ValueError as exc:
        raise ValueError(f"jump_times_s: {exc}") from exc


def jump_plan_parameters(jumps: Iterable[JumpLike]) -> dict[str, list[float] | list[str]]:
    """The node parameters (flat arrays) describing scenario jumps, for a params file."""
    jumps = list(jumps)
    return {
        "jump_times_s": [float(j.time_s) for j in jumps],
        "jump_forces_n": [float(f) for j in jumps for f in j.force_n],
        "jump_durations_s": [float(j.duration_s) for j in jumps],
        "jump_hemis": [str(j.hemi) for j in jumps],
        "jump_forces_b_n": [
            float(f) for j in jumps for f in getattr(j, "force_b_n", (0.0, 0.0, 0.0))
        ],
        "jump_couples_n": [float(getattr(j, "couple_n", 0.0)) for j in jumps],
    }


# --- configuration and outputs -------------------------------------------------------------


@dataclass(frozen=True)
class GaitConfig:
    """Thresholds, plan and references of the gait phase machine (validated).

    The fields made with ``parameter_field`` are the ``gait_phase_manager`` node's
    parameters of the same names (declared from here: default, range, live or not).
    """

    jumps: tuple[PlannedJump, ...] = ()
    stance_force_threshold_n: float = parameter_field(
        2.0, "normal force above which a hemi is in stance [N]", bounds=(1e-3, 1e4), live=True
    )
    touchdown_debounce_s: float = parameter_field(
        0.05, "stance this long without a break means touchdown [s]", bounds=(0.0, 1.0), live=True
    )
    liftoff_debounce_s: float = parameter_field(
        0.15, "no stance for longer than this means lift-off [s]", bounds=(0.0, 1.0), live=True
    )
    landed_speed_m_s: float = parameter_field(
        0.05, "COM speed below which the robot is at rest [m/s]", bounds=(1e-4, 10.0), live=True
    )
    landed_angular_speed_rad_s: float = parameter_field(
        0.05, "body rate below which the robot is at rest [rad/s]", bounds=(1e-4, 10.0), live=True
    )
    landed_dwell_s: float = parameter_field(
        1.0, "time at rest in stance before LANDED [s]", bounds=(0.0, 60.0), live=True
    )
    jump_settle_speed_m_s: float = parameter_field(
        0.1,
        "a jump after a touchdown waits until the COM's vertical speed is below this: the "
        "touchdown absorbed [m/s]",
        bounds=(1e-4, 10.0),
        live=True,
    )
    jump_settle_angular_speed_rad_s: float = parameter_field(
        0.05,
        "a jump after a touchdown waits until |w| is below this: the spin stopped by the "
        "feet's friction [rad/s]",
        bounds=(1e-4, 10.0),
        live=True,
    )
    jump_level_slope_deg: float = parameter_field(
        1.0,
        "ground flatter than this under a standing robot (its measured belly axis) is "
        "level; on a steeper one a jump heading downhill is scaled to meet the plane no "
        "faster than it would meet level ground (90: never scale) [deg]",
        bounds=(0.0, 90.0),
    )
    w_ref_rad_s: tuple[float, float, float] = parameter_field(
        (0.0, 1.0, 0.0), "flight angular velocity reference, base frame [rad/s]", length=3
    )
    landing_w_ref_rad_s: tuple[float, float, float] = parameter_field(
        (0.0, 0.0, 0.0), "angular velocity reference during landing, base frame [rad/s]", length=3
    )
    touchdown_height_m: float = parameter_field(
        0.6,
        "height of a hemi body at which its legs meet the ground: the stance shape's lowest "
        "limb (0.2 m) plus the legs' 0.4 m stroke [m]",
        bounds=(0.0, 10.0),
        live=True,
    )
    stance_lead_s: float = parameter_field(
        0.8,
        "the limbs are handed back to the legs (stance shape) this long before the predicted "
        "touchdown; 0: at contact [s]",
        bounds=(0.0, 10.0),
        live=True,
    )
    landing_spin_up_rad_s: float = parameter_field(
        0.0,
        "landing_timed: where no steady spin within the reel's reach times the landing, "
        "spin up to this first, then back (0: steady spins only) [rad/s]",
        bounds=(0.0, 10.0),
        live=True,
    )
    landing_spin_up_settle_s: float = parameter_field(
        1.5,
        "landing_timed: a spin-up ends at least this long before the predicted touchdown, "
        "for the reel to pay back out [s]",
        bounds=(0.0, 10.0),
        live=True,
    )
    landing_radius_x_max_m: float = parameter_field(
        RobotModel().radius_x_max_m,
        "landing_timed: the farthest a hemi reels out from the centre of mass (half the "
        "longest tether), which sets the slowest spin a timing can ask for [m]",
        bounds=(0.1, 100.0),
        live=True,
    )
    attitude_reference: str = parameter_field(
        "integrate_w_ref",
        "attitude reference: hold the first measured attitude (initial), propagate it with "
        "w_ref (integrate_w_ref), or propagate it with w_ref after turning the body axis of "
        "w_ref onto the measured angular momentum (momentum_aligned); landing_timed: from "
        "every lift-off a spin about the belly timed to meet the ground with the tether "
        "level, held to the touchdown (as integrate_w_ref when there is nothing to time)",
        choices=ATTITUDE_REFERENCE_MODES,
    )

    def __post_init__(self) -> None:
        validate_jump_plan(self.jumps)
        positive = {
            "stance_force_threshold_n": self.stance_force_threshold_n,
            "landed_speed_m_s": self.landed_speed_m_s,
            "landed_angular_speed_rad_s": self.landed_angular_speed_rad_s,
            "jump_settle_speed_m_s": self.jump_settle_speed_m_s,
            "jump_settle_angular_speed_rad_s": self.jump_settle_angular_speed_rad_s,
        }
        for name, value in positive.items():
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name}: must be finite and > 0, got {value}")
        for name in (
            "touchdown_debounce_s",
            "liftoff_debounce_s",
            "landed_dwell_s",
            "touchdown_height_m",
            "stance_lead_s",
            "jump_level_slope_deg",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name}: must be finite and >= 0, got {value}")
        _vector3(self.w_ref_rad_s, "w_ref_rad_s")
        _vector3(self.landing_w_ref_rad_s, "landing_w_ref_rad_s")
        if self.attitude_reference not in ATTITUDE_REFERENCE_MODES:
            raise ValueError(
                f"attitude_reference: must be one of {ATTITUDE_REFERENCE_MODES}, "
                f"got {self.attitude_reference!r}"
            )

    @property
    def touchdown_debounce_ns(self) -> int:
        """[ns] stance at least this long means touchdown."""
        return seconds_to_ns(self.touchdown_debounce_s)

    @property
    def liftoff_debounce_ns(self) -> int:
        """[ns] no stance for longer than this means lift-off."""
        return seconds_to_ns(self.liftoff_debounce_s)

    @property
    def landed_dwell_ns(self) -> int:
        """[ns] at rest on both hemis this long means LANDED."""
        return seconds_to_ns(self.landed_dwell_s)

    @property
    def needs_principal_inertia(self) -> bool:
        """Whether :meth:`GaitPhaseMachine.update` needs the measured principal moments."""
        return self.attitude_reference in ("momentum_aligned", "landing_timed")


def gait_config_from_parameters(params: Mapping[str, Any]) -> GaitConfig:
    """The machine's configuration from the node's parameters (seconds, flat jump arrays).

    ``params`` uses the names of ``config/gait_phase_manager.yaml`` (its
    ``ros__parameters`` mapping, optionally updated with
    :func:`jump_plan_parameters`); missing ones take :class:`GaitConfig`'s
    defaults and other keys are ignored. The node and the library closed loop
    both build their machine here, so they agree. ``ValueError`` names the
    parameter.
    """
    jumps = jump_plan_from_arrays(
        list(params.get("jump_times_s") or []),
        list(params.get("jump_forces_n") or []),
        list(params.get("jump_durations_s") or []),
        [str(h) for h in params.get("jump_hemis") or []],
        list(params.get("jump_forces_b_n") or []),
        couples_n=list(params.get("jump_couples_n") or []),
    )
    values: dict[str, Any] = {}
    for name, default, _info in parameter_fields(GaitConfig):
        value = params.get(name, default)
        if isinstance(default, tuple):
            v = _vector3(value, name)
            values[name] = (float(v[0]), float(v[1]), float(v[2]))
        else:
            values[name] = str(value) if isinstance(default, str) else float(value)
    return GaitConfig(jumps=jumps, **values)


@dataclass(frozen=True)
class AttitudeReference:
    """Angular velocity reference and the attitude reference at ``stamp_ns``."""

    stamp_ns: int
    w_ref_rad_s: NDArray[np.float64]  # [rad/s] body frame
    q_ref_wxyz: NDArray[np.float64]  # world <- base at stamp_ns
    propagate: bool  # True: q_ref moves with w_ref; False: q_ref is held

    def restamped(self, t_ns: int) -> AttitudeReference:
        """The same reference stated at ``t_ns`` (its attitude there): a consumer admits
        only references stamped at or after the tick it last answered."""
        return AttitudeReference(
            t_ns, self.w_ref_rad_s.copy(), self.attitude_at(t_ns), self.propagate
        )

    def attitude_at(self, t_ns: int) -> NDArray[np.float64]:
        """The attitude reference at ``t_ns``."""
        if not self.propagate:
            return self.q_ref_wxyz.copy()
        return propagate_attitude(
            self.q_ref_wxyz, self.w_ref_rad_s, (t_ns - self.stamp_ns) / NS_PER_S
        )


@dataclass(frozen=True)
class GaitOutput:
    """What one tick of the machine decides."""

    t_ns: int
    phase: GaitPhase
    phase_changed: bool
    jump_force_n: NDArray[np.float64]  # [N] world, zero when not thrusting
    jump_torque_nm: NDArray[np.float64]  # [Nm] world, about the centre of mass
    pushing_hemi: str | None  # "a" / "b" while thrusting
    reference: AttitudeReference | None  # set on the ticks it changes
    stance: tuple[bool, bool]  # hemi a, hemi b
    hemi_height_m: tuple[float, float] = field(default=(0.0, 0.0))  # [m] world z of the bodies
    jumps_done: int = 0  # thrusts completed
    jumps_planned: int = 0
    time_in_phase_ns: int = 0  # [ns]
    jump_waiting: bool = False  # a jump is due but its hemi is not in stance or not settled
    on_ground: bool = False  # debounced ground contact (touchdown / lift-off events)
    reason: str = ""  # why the phase changed, on the tick it changed
    touchdown_in_s: float = math.inf  # [s] predicted time to the next touchdown (inf: none)
    stance_shape: bool = False  # the limbs are legs: on the ground or touchdown within the lead
    jump_speed_scale: float = 1.0  # the running thrust's lift-off speed factor (downhill < 1)

    @property
    def thrusting(self) -> bool:
        """True while a planned thrust is being applied."""
        return self.pushing_hemi is not None


@dataclass
class _Thrust:
    index: int
    hemi: str
    end_ns: int
    jump: PlannedJump  # as pushed: the plan's, scaled for a downhill slope
    speed_scale: float = 1.0


# --- the machine -----------------------------------------------------------------------------
class GaitPhaseMachine:
    """Deterministic gait phase state machine; call :meth:`update` once per control tick.

    ``gravity_m_s2`` [m/s^2] predicts the touchdown (:func:`predicted_touchdown_s`);
    with ``mass_kg`` [kg] (default: the nominal :class:`RobotModel`'s) it scales a
    downhill jump (:func:`downhill_speed_scale`).
    """

    def __init__(
        self, config: GaitConfig, gravity_m_s2: float = 0.0, mass_kg: float | None = None
    ) -> None:
        if not (math.isfinite(gravity_m_s2) and gravity_m_s2 >= 0.0):
            raise ValueError(f"gravity_m_s2: must be finite and >= 0, got {gravity_m_s2}")
        mass = RobotModel().total_mass_kg if mass_kg is None else float(mass_kg)
        if not (math.isfinite(mass) and mass > 0.0):
            raise ValueError(f"mass_kg: must be finite and > 0, got {mass_kg}")
        self.gravity_m_s2 = float(gravity_m_s2)
        self.mass_kg = mass  # [kg] the robot's, as the gait's model has it
        self.config = config
        self._phase: GaitPhase | None = None
        self._phase_since_ns = 0
        self._last_t_ns: int | None = None
        self._next_jump = 0
        self._jumps_done = 0
        self._thrust: _Thrust | None = None
        self._thrust_ended_ns: int | None = None
        self._on_ground = False
        self._stance_since_ns: int | None = None  # start of the current stance streak
        self._last_stance_ns: int | None = None
        self._at_rest_since_ns: int | None = None
        self._reference: AttitudeReference | None = None
        self._landing_reference_set = False
        self._spin_up_end: AttitudeReference | None = None  # a timed landing's second spin
        self._flight_timed = False  # this flight's landing is timed (landing_timed)

    @property
    def phase(self) -> GaitPhase | None:
        """The current phase (None before the first update)."""
        return self._phase

    @property
    def reference(self) -> AttitudeReference | None:
        """The current attitude reference (None before the first update)."""
        return self._reference

    @property
    def jumps_done(self) -> int:
        """Thrusts completed so far."""
        return self._jumps_done

    def update(  # noqa: PLR0917 (the positional signature shared with the closed loop)
        self,
        t_ns: int,
        position_m: ArrayLike,
        velocity_m_s: ArrayLike,
        orientation_wxyz: ArrayLike,
        angular_velocity_rad_s: ArrayLike,
        radius_x_m: float,
        contact_normal_force_n: ArrayLike,
        principal_inertia_kg_m2: ArrayLike | None = None,
    ) -> GaitOutput:
        """Advance to tick ``t_ns`` with the measured state.

        ``velocity_m_s`` is the world-frame centre-of-mass velocity,
        ``angular_velocity_rad_s`` the body rate, ``radius_x_m`` the distance of a
        hemi body from the centre of mass along the tether,
        ``contact_normal_force_n`` the ground normal force on (hemi a, hemi b) and
        ``principal_inertia_kg_m2`` the measured (Ixx, Iyy, Izz) [kg m^2] (required
        by ``attitude_reference: momentum_aligned``, optional otherwise).
        ``t_ns`` must increase from call to call; inputs must be finite and the
        moments > 0 (``ValueError`` naming the input otherwise, the machine's
        state unchanged).
        """
        t_ns = int(t_ns)
        if self._last_t_ns is not None and t_ns <= self._last_t_ns:
            raise ValueError(f"t_ns {t_ns} does not follow the previous tick {self._last_t_ns}")
        position = _vector3(position_m, "position_m")
        velocity = _vector3(velocity_m_s, "velocity_m_s")
        rate = _vector3(angular_velocity_rad_s, "angular_velocity_rad_s")
        q = _quaternion(orientation_wxyz, "orientation_wxyz")
        radius_x = float(radius_x_m)
        if not (math.isfinite(radius_x) and radius_x > 0.0):
            raise ValueError(f"radius_x_m: must be finite and > 0, got {radius_x_m}")
        normal = np.asarray(contact_normal_force_n, dtype=float).reshape(-1)
        if normal.shape != (2,) or not np.all(np.isfinite(normal)):
            raise ValueError(f"contact_normal_force_n: expected 2 finite numbers, got {normal}")
        inertia = None
        if principal_inertia_kg_m2 is not None:
            inertia = _principal_inertia(principal_inertia_kg_m2, "principal_inertia_kg_m2")
        elif self.config.attitude_reference == "momentum_aligned":
            raise ValueError(
                "principal_inertia_kg_m2: required by attitude_reference 'momentum_aligned'"
            )

        cfg = self.config
        first = self._phase is None
        self._last_t_ns = t_ns
        stance = (
            bool(normal[0] > cfg.stance_force_threshold_n),
            bool(normal[1] > cfg.stance_force_threshold_n),
        )
        heights = tuple(
            float(position[2] + hemi_offset_world(q, radius_x, hemi)[2]) for hemi in names.HEMIS
        )
        contact_event = self._debounce_contact(t_ns, stance, first)

        # Thrust: finish the running one (its duration is over, or the robot has left the
        # ground), then start a due one from a ground phase when its hemi is in stance.
        if self._thrust is not None and (t_ns >= self._thrust.end_ns or contact_event == "liftoff"):
            _LOG.debug("jump %d thrust ends at t = %d ns", self._thrust.index, t_ns)
            self._thrust = None
            self._jumps_done += 1
            self._thrust_ended_ns = t_ns
        jump_waiting = False
        ground_phase = first or self._phase in _GROUND_PHASES
        if self._thrust is None and self._next_jump < len(cfg.jumps) and ground_phase:
            jump = cfg.jumps[self._next_jump]
            if t_ns >= jump.time_ns:
                hemi = _pushing_hemi(jump.hemi, stance)
                settled = self._phase != GaitPhase.JUMP or (
                    abs(float(velocity[2])) < cfg.jump_settle_speed_m_s
                    and float(np.linalg.norm(rate)) < cfg.jump_settle_angular_speed_rad_s
                )
                if hemi is None or not settled:
                    jump_waiting = True
                else:
                    _LOG.debug(
                        "jump %d starts at t = %d ns through hemi %s", self._next_jump, t_ns, hemi
                    )
                    speed_scale = downhill_speed_scale(
                        jump.total_force_n,
                        rotation_matrix(q)[:, 2],
                        self.mass_kg,
                        self.gravity_m_s2,
                        cfg.jump_level_slope_deg,
                    )
                    if speed_scale < 1.0:
                        _LOG.info(
                            "jump %d heads downhill: lift-off speed scaled by %.3f",
                            self._next_jump,
                            speed_scale,
                        )
                    self._thrust = _Thrust(
                        self._next_jump,
                        hemi,
                        t_ns + jump.duration_ns,
                        scaled_jump(jump, speed_scale, self.mass_kg * self.gravity_m_s2),
                        speed_scale,
                    )
                    self._next_jump += 1

        phase, reason = self._next_phase(t_ns, stance, velocity, rate, contact_event)
        changed = phase != self._phase
        if changed:
            if self._phase is not None and (self._phase, phase) not in ALLOWED_TRANSITIONS:
                raise AssertionError(f"gait phase {self._phase} -> {phase} is not allowed")
            _LOG.debug("gait phase %s -> %s at t = %d ns (%s)", self._phase, phase, t_ns, reason)
            self._phase = phase
            self._phase_since_ns = t_ns

        touchdown_in_s = (
            0.0
            if self._on_ground
            else predicted_touchdown_s(
                min(heights), float(velocity[2]), self.gravity_m_s2, cfg.touchdown_height_m
            )
        )
        reference = None
        landing = phase in _LANDING_PHASES
        timed = cfg.attitude_reference == "landing_timed"
        if contact_event is not None:
            self._spin_up_end = None
            self._flight_timed = False
        if timed and contact_event == "liftoff":  # a new flight: time its landing
            assert inertia is not None  # needs_principal_inertia
            plan = self._timed_landing(
                t_ns,
                q=q,
                rate=rate,
                inertia=inertia,
                radius_x=radius_x,
                touchdown_in_s=touchdown_in_s,
            )
            if plan is not None:
                self._flight_timed = True
                self._landing_reference_set = self._landing_reference_set or landing
                reference = AttitudeReference(
                    stamp_ns=t_ns, w_ref_rad_s=plan[1], q_ref_wxyz=plan[0], propagate=True
                )
                _LOG.debug(
                    "landing timed at t = %d ns: %.3f rad/s about the belly, touchdown in %.2f s",
                    t_ns,
                    float(np.linalg.norm(plan[1])),
                    touchdown_in_s,
                )
            elif not landing:  # nothing to time: the flight reference, from here
                reference = self._new_reference(t_ns, q, rate, inertia, False)
        if (
            reference is None
            and self._spin_up_end is not None
            and t_ns >= self._spin_up_end.stamp_ns
        ):
            reference, self._spin_up_end = self._spin_up_end.restamped(t_ns), None
            _LOG.debug("timed landing: spin-up over at t = %d ns", t_ns)
        if reference is None and landing and self._flight_timed and not self._landing_reference_set:
            # Landing starts in a timed flight: the timing holds to the touchdown.
            self._landing_reference_set = True
            assert self._reference is not None  # set at the lift-off
            reference = self._reference.restamped(t_ns)
        if reference is None and (first or (landing and not self._landing_reference_set)):
            reference = self._new_reference(t_ns, q, rate, inertia, landing)
        if reference is not None:
            self._reference = reference
        if self._thrust is not None:
            force, torque = _split_jump_wrench(self._thrust.jump, q, radius_x, self._thrust.hemi)
            pushing: str | None = self._thrust.hemi
        else:
            force, torque, pushing = np.zeros(3), np.zeros(3), None
        return GaitOutput(
            t_ns=t_ns,
            phase=phase,
            phase_changed=changed,
            jump_force_n=force,
            jump_torque_nm=torque,
            pushing_hemi=pushing,
            reference=reference,
            stance=stance,
            hemi_height_m=(heights[0], heights[1]),
            jumps_done=self._jumps_done,
            jumps_planned=len(cfg.jumps),
            time_in_phase_ns=t_ns - self._phase_since_ns,
            jump_waiting=jump_waiting,
            touchdown_in_s=touchdown_in_s,
            stance_shape=self._on_ground
            or (float(velocity[2]) < 0.0 and touchdown_in_s <= cfg.stance_lead_s),
            on_ground=self._on_ground,
            reason=reason if changed else "",
            jump_speed_scale=self._thrust.speed_scale if self._thrust is not None else 1.0,
        )

    # -- internals -------------------------------------------------------------------------
    def _timed_landing(
        self,
        t_ns: int,
        *,
        q: NDArray[np.float64],
        rate: NDArray[np.float64],
        inertia: NDArray[np.float64],
        radius_x: float,
        touchdown_in_s: float,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """The first reference of a timed landing; a spin-up's end is kept for later."""
        cfg = self.config
        if cfg.landing_spin_up_rad_s <= 0.0:
            return timed_landing_reference(q, rate, inertia, touchdown_in_s)
        # the moment about the belly scales with r_x^2 (the hemis' masses dominate it)
        reach = min(1.0, radius_x / cfg.landing_radius_x_max_m) ** 2
        plan = timed_landing_plan(
            q,
            rate,
            inertia,
            touchdown_in_s,
            slowest_fraction=max(reach, 1e-6),
            spin_up_rad_s=cfg.landing_spin_up_rad_s,
            settle_s=cfg.landing_spin_up_settle_s,
        )
        if plan is None:
            return None
        if plan.spin_up_s > 0.0:
            q_switch, w_switch = plan.switch()
            self._spin_up_end = AttitudeReference(
                stamp_ns=t_ns + seconds_to_ns(plan.spin_up_s),
                w_ref_rad_s=w_switch,
                q_ref_wxyz=q_switch,
                propagate=True,
            )
            _LOG.debug(
                "landing timed with a spin-up: %.3f rad/s for %.2f s, then %.3f rad/s",
                plan.spin_up_rad_s,
                plan.spin_up_s,
                plan.landing_rate_rad_s,
            )
        return plan.attitude_wxyz, plan.spin_axis_body * plan.spin_up_rad_s

    def _debounce_contact(self, t_ns: int, stance: tuple[bool, bool], first: bool) -> str | None:
        """Update the debounced ground contact; the event of this tick, if any.

        Touchdown: some hemi in stance without a break for ``touchdown_debounce``;
        lift-off: no hemi in stance for longer than ``liftoff_debounce``. On the
        first tick the measured stance is taken as it is (a robot starting on its
        feet is on the ground).
        """
        cfg = self.config
        if any(stance):
            self._last_stance_ns = t_ns
            if self._stance_since_ns is None:
                self._stance_since_ns = t_ns
        else:
            self._stance_since_ns = None
        if first:
            self._on_ground = any(stance)
            return None
        if not self._on_ground:
            if (
                self._stance_since_ns is not None
                and t_ns - self._stance_since_ns >= cfg.touchdown_debounce_ns
            ):
                self._on_ground = True
                return "touchdown"
            return None
        if self._last_stance_ns is None or t_ns - self._last_stance_ns > cfg.liftoff_debounce_ns:
            self._on_ground = False
            return "liftoff"
        return None

    def _new_reference(
        self,
        t_ns: int,
        q: NDArray[np.float64],
        rate: NDArray[np.float64],
        inertia: NDArray[np.float64] | None,
        landing: bool,
    ) -> AttitudeReference:
        cfg = self.config
        w_ref = np.array(cfg.landing_w_ref_rad_s if landing else cfg.w_ref_rad_s, dtype=float)
        if landing:
            self._landing_reference_set = True
        q_ref, propagate = attitude_reference_at_stamp(
            cfg.attitude_reference, q, rate, inertia, w_ref
        )
        return AttitudeReference(
            stamp_ns=t_ns, w_ref_rad_s=w_ref, q_ref_wxyz=q_ref, propagate=propagate
        )

    def _next_phase(
        self,
        t_ns: int,
        stance: tuple[bool, bool],
        velocity: NDArray[np.float64],
        rate: NDArray[np.float64],
        event: str | None,
    ) -> tuple[GaitPhase, str]:
        """The phase of this tick and, when it changes, why (module docstring)."""
        cfg = self.config
        phase = self._phase
        jumps_left = self._next_jump < len(cfg.jumps) or self._thrust is not None
        if phase is None:  # the first tick
            if self._on_ground:
                if jumps_left:
                    return GaitPhase.LAUNCH, "start on the ground, a jump planned"
                return GaitPhase.LANDING, "start on the ground, no jump planned"
            return GaitPhase.IN_FLIGHT, "start in the air"
        if phase in _GROUND_PHASES:  # LAUNCH, JUMP
            if event == "liftoff":
                if jumps_left or not self._descending_after_jumps(velocity):
                    return GaitPhase.IN_FLIGHT, "lift-off"
                return GaitPhase.LANDING, "lift-off after the last jump, descending"
            stayed = (
                self._thrust_ended_ns is not None
                and t_ns - self._thrust_ended_ns > cfg.liftoff_debounce_ns
            )
            if not jumps_left and self._thrust is None and self._on_ground and stayed:
                return GaitPhase.LANDING, "last jump done without leaving the ground"
            return phase, ""
        if phase == GaitPhase.IN_FLIGHT:
            if event == "touchdown":
                if jumps_left:
                    return GaitPhase.JUMP, "touchdown, a jump planned"
                return GaitPhase.LANDING, "touchdown, no jump left"
            if not jumps_left and self._descending_after_jumps(velocity):
                return GaitPhase.LANDING, "descending after the last jump: landing"
            return phase, ""
        if phase == GaitPhase.LANDING:
            at_rest = (
                all(stance)
                and self._on_ground
                and float(np.linalg.norm(velocity)) < cfg.landed_speed_m_s
                and float(np.linalg.norm(rate)) < cfg.landed_angular_speed_rad_s
            )
            if not at_rest:
                self._at_rest_since_ns = None
                return phase, ""
            if self._at_rest_since_ns is None:
                self._at_rest_since_ns = t_ns
            if t_ns - self._at_rest_since_ns >= cfg.landed_dwell_ns:
                return GaitPhase.LANDED, "at rest on both hemis"
            return phase, ""
        return phase, ""  # LANDED is final

    def _descending_after_jumps(self, velocity: NDArray[np.float64]) -> bool:
        """All planned jumps done (at least one) and the centre of mass going down."""
        return self._jumps_done > 0 and float(velocity[2]) <= 0.0


_GROUND_PHASES = (GaitPhase.LAUNCH, GaitPhase.JUMP)
_LANDING_PHASES = (GaitPhase.LANDING, GaitPhase.LANDED)
# The phase changes the machine makes (DESIGN.md section 4 and a jump that never leaves
# the ground, or a touchdown before a planned landing); LANDED is final.
ALLOWED_TRANSITIONS: frozenset[tuple[GaitPhase, GaitPhase]] = frozenset(
    {
        (GaitPhase.LAUNCH, GaitPhase.IN_FLIGHT),
        (GaitPhase.LAUNCH, GaitPhase.LANDING),
        (GaitPhase.IN_FLIGHT, GaitPhase.JUMP),
        (GaitPhase.IN_FLIGHT, GaitPhase.LANDING),
        (GaitPhase.JUMP, GaitPhase.IN_FLIGHT),
        (GaitPhase.JUMP, GaitPhase.LANDING),
        (GaitPhase.LANDING, GaitPhase.LANDED),
    }
)


def _pushing_hemi(planned: str, stance: tuple[bool, bool]) -> str | None:
    """The hemi that pushes now ("a", "b", or "auto": all in stance; "both": each its own
    force, both in stance), or None if none may."""
    if planned == "both":
        return "both" if all(stance) else None
    if planned != "auto":
        return planned if stance[HEMI_INDEX[planned]] else None
    in_stance = [hemi for hemi, s in zip(names.HEMIS, stance, strict=True) if s]
    if not in_stance:
        return None
    return in_stance[0] if len(in_stance) == 1 else "auto"


def _split_jump_wrench(
    jump: PlannedJump, orientation_wxyz: ArrayLike, radius_x_m: float, hemi: str
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Force [N] and torque about the COM [Nm] of a thrust through one hemi, shared by
    both ("auto") or pushed by both at once, each its own force ("both").

    ``"auto"`` shares the force equally between the two hemis (both in stance). Either
    adds the jump's couple (:class:`PlannedJump`, :func:`spin_couple_n`).
    """
    if hemi == "both":
        forces = [np.asarray(jump.force_n, dtype=float), np.asarray(jump.force_b_n, dtype=float)]
    elif hemi == "auto":
        forces = [np.asarray(jump.force_n, dtype=float) / 2.0] * 2
    else:
        return jump_wrench(jump.force_n, orientation_wxyz, radius_x_m, hemi)
    couple = spin_couple_n(orientation_wxyz, jump.couple_n)
    force = np.zeros(3)
    torque = np.zeros(3)
    for side, base, sign in zip(names.HEMIS, forces, (1.0, -1.0), strict=True):
        f, tau = jump_wrench(base + sign * couple, orientation_wxyz, radius_x_m, side)
        force += f
        torque += tau
    return force, torque


def spin_couple_n(orientation_wxyz: ArrayLike, couple_n: float) -> NDArray[np.float64]:
    """Hemi a's share [N] (world) of a couple about the vertical: ``couple_n`` along
    ``z x t``, ``t`` the tether's horizontal direction (body x, hemi b to a); hemi b
    pushes the opposite. Zero for a tether along the vertical (no lever about it)."""
    tether = rotation_matrix(_quaternion(orientation_wxyz, "orientation_wxyz"))[:, 0]
    across = np.array([-tether[1], tether[0], 0.0])  # z x tether
    size = float(np.linalg.norm(across))
    if couple_n == 0.0 or size < 1e-6:
        return np.zeros(3)
    return across * (couple_n / size)
