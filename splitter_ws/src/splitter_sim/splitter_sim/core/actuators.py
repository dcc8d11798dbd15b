"""Joint and tether actuators: limits, command validation and a rate/acceleration-limited servo.

The 25 actuated coordinates (``names.JOINT_NAMES`` order: 8 limbs x (hip
abduction, hip pitch, knee), then the prismatic tether) follow their commands
as position servos whose velocity and acceleration never exceed the hardware
limits of :class:`~splitter_model.model.RobotModel` (actuator output speed
800 RPM, peak torque over the limb-tip inertia, reel speed and start-up).

Within one simulation step the servo acceleration is constant, so the joint
trajectory is an exact quadratic in time and the integrator can evaluate the
shape at any of its stage times. The acceleration is chosen by a discrete-time
law that (1) never lets the closing speed exceed what full braking can still stop
within the remaining distance, so the joint stops on its target without
overshoot, and (2) switches to a two-step deadbeat when that is reachable within
the limits, so it arrives exactly, at rest.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.actuators import N_JOINTS, ActuatorLimits

# A command's velocity feed-forward extrapolates its position target for at most
# this long; a stale command then holds position (no drift into a limit).
COMMAND_EXTRAPOLATION_S = 0.02  # [s] two control periods of 10 ms
# A point that arrives after its stamp finds the servos on the previous trajectory, off
# the new one in position by (v_old - v_new) x lateness; that offset is blended out over
# this many times the lateness (at least LATE_BLEND_MIN_S) instead of being closed at
# the servo's full acceleration. The velocity switches at once, as on a point on time.
LATE_BLEND_FACTOR = 2.0  # [-]
LATE_BLEND_MIN_S = 0.04  # [s]
ARRIVAL_TOLERANCE = 1e-12  # [rad or m] / [rad/s or m/s]: snap to the target below this


def validate_joint_command(
    limits: ActuatorLimits,
    position: ArrayLike,
    velocity: ArrayLike | None = None,
    joint_names: tuple[str, ...] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(position, velocity) as float arrays, or ``ValueError`` naming the offending joint.

    Positions must lie within the joint / tether range, velocities within the
    actuator speed; everything finite, 25 values each.
    """
    q = np.array(position, dtype=float).reshape(-1)
    qd = np.zeros(N_JOINTS) if velocity is None else np.array(velocity, dtype=float).reshape(-1)
    # Fast path (a command arrives every control period): comparisons with NaN are
    # false and the limits are finite, so this accepts exactly the valid commands.
    if (
        q.shape == (N_JOINTS,)
        and qd.shape == (N_JOINTS,)
        and ((q >= limits.position_min) & (q <= limits.position_max)).all()
        and (velocity is None or (np.abs(qd) <= limits.speed_max).all())
    ):
        return q, qd
    for label, arr in (("position", q), ("velocity", qd)):
        if arr.shape != (N_JOINTS,):
            raise ValueError(f"joint command {label}: expected {N_JOINTS} values, got {arr.size}")
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            raise ValueError(
                f"joint command {label} of {_name(bad[0], joint_names)} is not finite "
                f"({arr[bad[0]]})"
            )
    out = np.flatnonzero((q < limits.position_min) | (q > limits.position_max))
    if out.size:
        i = out[0]
        raise ValueError(
            f"joint command position of {_name(i, joint_names)} = {q[i]:.6g} is outside "
            f"[{limits.position_min[i]:.6g}, {limits.position_max[i]:.6g}]"
        )
    fast = np.flatnonzero(np.abs(qd) > limits.speed_max)
    if fast.size:
        i = fast[0]
        raise ValueError(
            f"joint command velocity of {_name(i, joint_names)} = {qd[i]:.6g} exceeds "
            f"the actuator speed {limits.speed_max[i]:.6g}"
        )
    return q, qd


def _name(index: int, joint_names: tuple[str, ...] | None) -> str:
    return f"joint {index}" if joint_names is None else f"'{joint_names[index]}'"


# The servo's formulas are written once, for numpy arrays (ARRAY_MATH) and for the
# CasADi symbols of the simulator's compiled kernels (the ``casadi`` module): ``ops``
# is a namespace of elementwise fabs, sign, sqrt, fmax, fmin, logic_and, logic_or and
# if_else (select), with casadi's names.
ARRAY_MATH = SimpleNamespace(
    fabs=np.abs,
    sign=np.sign,
    sqrt=np.sqrt,
    fmax=np.maximum,
    fmin=np.minimum,
    logic_and=np.logical_and,
    logic_or=np.logical_or,
    if_else=np.where,
)


def safe_closing_speed(
    distance: NDArray[np.float64],
    closing_speed: NDArray[np.float64],
    accel_max: NDArray[np.float64],
    dt: float,
    ops: Any = ARRAY_MATH,
) -> NDArray[np.float64]:
    """Largest closing speed at the end of this step from which the servo still stops in time.

    With constant acceleration per step, stopping from speed ``v`` in ``k`` steps of
    at most ``a`` covers at most ``v^2 / (2 a) + v dt / 2``; a state is safe when that
    fits in the remaining distance. Requiring it at the end of the step, whose
    distance is ``d - (v_now + v_end) dt / 2``, gives
    ``v_end <= -a dt + sqrt((a dt)^2 - a dt v_now + 2 a d)``. Full braking keeps a
    safe state safe, so the servo never overshoots a resting target.
    """
    a_dt = accel_max * dt
    radicand = a_dt * a_dt - a_dt * closing_speed + 2.0 * accel_max * distance
    return -a_dt + ops.sqrt(ops.fmax(radicand, 0.0))


def servo_acceleration(  # noqa: PLR0917  (the servo state and target, in order)
    q: NDArray[np.float64],
    qd: NDArray[np.float64],
    q_target: NDArray[np.float64],
    qd_target: NDArray[np.float64],
    limits: ActuatorLimits,
    dt: float,
) -> NDArray[np.float64]:
    """Constant acceleration for the coming step of every actuator.

    The target moves at ``qd_target``; in error coordinates ``e = q_target - q``
    the law brings ``(e, de/dt)`` to ``(0, 0)``. The two-step deadbeat
    ``a0 = (e + 3/2 de dt) / dt^2`` (then ``a1 = de/dt - a0``) is used when both
    accelerations and the intermediate speed respect the limits and the error
    reaches zero without changing sign; otherwise the servo accelerates toward
    the largest safe closing speed (:func:`safe_closing_speed`), saturated.
    """
    return servo_law(
        ARRAY_MATH, q, qd, q_target, qd_target, limits.acceleration_max, limits.speed_max, dt
    )


def servo_law(  # noqa: PLR0917  (the servo state, target and limits, in order)
    ops: Any,
    q: Any,
    qd: Any,
    q_target: Any,
    qd_target: Any,
    a_max: Any,
    v_max: Any,
    dt: Any,
) -> Any:
    """:func:`servo_acceleration` for arrays or symbols, with the math namespace ``ops``."""
    e = q_target - q
    de = qd_target - qd
    a0 = (e + 1.5 * de * dt) / (dt * dt)
    a1 = de / dt - a0
    e1 = e + de * dt - 0.5 * a0 * dt * dt
    de1 = de - a0 * dt
    both = ops.logic_and
    deadbeat = both(
        both(
            both(ops.fabs(a0) <= a_max, ops.fabs(a1) <= a_max),
            both(ops.fabs(qd + a0 * dt) <= v_max, e * e1 >= 0.0),
        ),
        both(de * de1 >= 0.0, e1 * de1 <= 0.0),
    )
    direction = ops.sign(e)
    closing = -direction * de
    v_end = safe_closing_speed(ops.fabs(e), closing, a_max, dt, ops)
    v_des = ops.fmin(ops.fmax(qd_target + direction * v_end, -v_max), v_max)
    a_track = ops.fmin(ops.fmax((v_des - qd) / dt, -a_max), a_max)
    return ops.if_else(deadbeat, a0, a_track)


def command_target(
    position: NDArray[np.float64],
    velocity: NDArray[np.float64],
    age_s: float,
    limits: ActuatorLimits,
    extrapolation_s: float = COMMAND_EXTRAPOLATION_S,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Target (position, velocity) of a command ``age_s`` old: extrapolated, then held."""
    if not velocity.any():
        return position, velocity
    horizon = min(max(age_s, 0.0), extrapolation_s)
    target = np.clip(position + velocity * horizon, limits.position_min, limits.position_max)
    moving = (age_s < extrapolation_s) & (target > limits.position_min)
    moving &= target < limits.position_max
    return target, np.where(moving, velocity, 0.0)


def advance(
    q: NDArray[np.float64], qd: NDArray[np.float64], qdd: NDArray[np.float64], tau: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Joint positions and velocities ``tau`` seconds into a constant-acceleration step."""
    return q + qd * tau + 0.5 * qdd * (tau * tau), qd + qdd * tau


def snap_arrived(
    q: NDArray[np.float64],
    qd: NDArray[np.float64],
    q_target: NDArray[np.float64],
    qd_target: NDArray[np.float64],
    free: NDArray[np.bool_] | None = None,
) -> bool:
    """Put joints within round-off of a resting target exactly on it; True if any moved.

    ``free``: joints that no longer follow their servo (faults), never snapped.
    """
    arrived = arrived_at_rest(ARRAY_MATH, q, qd, q_target, qd_target)
    if free is not None:
        arrived &= ~free
    if not arrived.any():
        return False
    q[arrived] = q_target[arrived]
    qd[arrived] = 0.0
    return True


def arrived_at_rest(ops: Any, q: Any, qd: Any, q_target: Any, qd_target: Any) -> Any:
    """Whether a joint is within round-off of its resting target but not exactly on it."""
    both = ops.logic_and
    return both(
        both(qd_target == 0.0, ops.fabs(q - q_target) <= ARRIVAL_TOLERANCE),
        both(ops.fabs(qd) <= ARRIVAL_TOLERANCE, ops.logic_or(q != q_target, qd != 0.0)),
    )


@dataclass(frozen=True)
class LateCommandBlend:
    """The position offset from a late point's trajectory to the servos' one, fading out.

    At ``start_ns`` the servos follow the previous command's trajectory (position
    ``q_old``) while the late point's is at ``q_new``: the reference becomes the new
    trajectory plus ``q_old - q_new``, which a smooth step (cubic Hermite, zero slope
    at both ends) takes to 0 over ``duration_s``. The position stays continuous, the
    velocity changes as on a point that comes on time, and the blend adds at most
    ``1.5 dq / T`` of velocity and ``6 dq / T^2`` of acceleration.
    """

    start_ns: int
    offset_q: NDArray[np.float64]
    duration_s: float

    @classmethod
    def between(
        cls,
        old: tuple[NDArray[np.float64], NDArray[np.float64]],
        new: tuple[NDArray[np.float64], NDArray[np.float64]],
        start_ns: int,
        late_ns: int,
    ) -> LateCommandBlend | None:
        """The blend from trajectory ``old`` to ``new`` (each (position, velocity) now)."""
        dq = old[0] - new[0]
        if not dq.any():
            return None
        duration = max(LATE_BLEND_FACTOR * late_ns * 1e-9, LATE_BLEND_MIN_S)
        return cls(int(start_ns), dq, duration)

    def active(self, t_ns: int) -> bool:
        """Whether the offset is still blending out at ``t_ns``."""
        return (t_ns - self.start_ns) * 1e-9 < self.duration_s

    def apply(
        self,
        t_ns: int,
        position: NDArray[np.float64],
        velocity: NDArray[np.float64],
        limits: ActuatorLimits,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The blended reference at ``t_ns`` from the new trajectory's (position, velocity)."""
        T = self.duration_s
        s = min(max((t_ns - self.start_ns) * 1e-9 / T, 0.0), 1.0)
        h00 = 2.0 * s**3 - 3.0 * s**2 + 1.0
        dh00 = (6.0 * s**2 - 6.0 * s) / T
        q = position + self.offset_q * h00
        v = velocity + self.offset_q * dh00
        q = np.clip(q, limits.position_min, limits.position_max)
        v = np.clip(v, -limits.speed_max, limits.speed_max)
        return q, v


def corner_blend(
    position: NDArray[np.float64],
    velocity: NDArray[np.float64],
    velocity_step: NDArray[np.float64],
    since_start_s: float,
    duration_s: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A piecewise-linear reference rounded at a corner by a parabolic blend.

    The corner (velocity ``v0`` before, ``v0 + velocity_step`` after) is at the middle
    of a blend of ``duration_s``; ``since_start_s`` counts from the blend's start (so
    in ``[0, duration_s / 2)`` the reference is still on the segment before the
    corner, after it in ``[-duration_s / 2, 0)`` measured from the blend's end, as
    negative values). Before the corner the reference is the incoming line plus
    ``dv s^2 / (2 T)``; after it the outgoing line plus ``dv (T/2 - s')^2 / (2 T)``
    with ``s'`` the time since the corner: position and velocity are continuous and
    the acceleration is ``dv / T`` throughout the blend.
    """
    T = duration_s
    s = since_start_s
    if s >= 0.0:  # before the corner, on the incoming segment
        return (
            position + velocity_step * (s * s / (2.0 * T)),
            velocity + velocity_step * (s / T),
        )
    r = -s  # time left to the blend's end, after the corner
    return (
        position + velocity_step * (r * r / (2.0 * T)),
        velocity - velocity_step * (r / T),
    )
