"""A discrete second-order (speed and acceleration) limiter for one actuated coordinate.

Each control period the coordinate moves ``x_new = x + v_new dt``. ``v_new`` heads
for the target as fast as the limits allow while staying able to stop at it (and
at the range ends) with the available deceleration. Priorities, highest first:
range, speed and acceleration of the actuator, then an optional cap on positive
acceleration (the taut-tether bound), which is relaxed only so far as never to
force the coordinate to speed up in the negative direction.

A target that moves (a reference trajectory played back tick by tick) may be given
its velocity: the coordinate then heads for it in the target's frame, at the
target's velocity plus a closing speed, instead of as if the target would stop
where it is now. Where the target's own stop needs more deceleration than the
caps allow, the coordinate overshoots it, braking at the caps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class AxisLimits:
    """Range, speed and acceleration limits of one coordinate (units of x, per s, per s^2)."""

    lower: float
    upper: float
    speed_max: float
    acceleration_max: float


def braking_speed(distance: float, deceleration: float, dt: float) -> float:
    """Largest speed from which steps of ``deceleration * dt`` stop within ``distance``.

    Exact for the discrete profile: moving at ``v = (m + f) a dt`` (integer ``m``,
    ``0 <= f < 1``) now and ``a dt`` slower each following step covers
    ``a dt^2 ((m + 1) f + m (m + 1) / 2)``. Each step of the profile is again the
    braking speed of the distance left, so a stop never needs more than ``a dt``.
    """
    if distance <= 0.0 or deceleration <= 0.0:
        return 0.0
    step = deceleration * dt
    units = distance / (step * dt)  # distance in a dt^2
    m = math.floor((math.sqrt(1.0 + 8.0 * units) - 1.0) / 2.0)
    f = min(1.0, max(0.0, (units - m * (m + 1) / 2.0) / (m + 1)))
    return (m + f) * step


def limited_step(
    x: float,
    v: float,
    target: float,
    dt: float,
    limits: AxisLimits,
    *,
    positive_acceleration_max: float = math.inf,
    approach_braking_max: float | None = None,
    target_velocity: float = 0.0,
    lower_braking_max: float | None = None,
) -> tuple[float, float]:
    """(x_new, v_new) one control period toward ``target``.

    ``positive_acceleration_max`` caps the increase of ``v`` per second; it also
    limits how hard a negative velocity may be braked, so an approach from above
    is planned with ``approach_braking_max`` (default: that cap at the current
    state; pass the cap at the target when it shrinks on the way), and the lower
    range end with ``lower_braking_max`` (default: the actuator's deceleration).
    ``target_velocity`` is the target's own velocity (0: a resting target).
    """
    a_max = limits.acceleration_max
    if approach_braking_max is None:
        approach_braking_max = positive_acceleration_max
    error = target - x
    if error >= 0.0:
        closing = min(error / dt, braking_speed(error, a_max, dt))
    else:
        brake = max(min(a_max, approach_braking_max), 0.0)
        closing = -min(-error / dt, braking_speed(-error, brake, dt))
    v_des = min(max(target_velocity + closing, -limits.speed_max), limits.speed_max)
    # actuator speed and acceleration, and stopping before the range ends
    v_lo = max(-limits.speed_max, v - a_max * dt, -braking_speed(x - limits.lower, a_max, dt))
    if lower_braking_max is not None:  # ... with a gentler braking, as far as the actuator can
        lower_brake = max(min(a_max, lower_braking_max), 0.0)
        gentle = -braking_speed(x - limits.lower, lower_brake, dt)
        v_lo = max(v_lo, min(gentle, v + a_max * dt))
    v_hi = min(limits.speed_max, v + a_max * dt, braking_speed(limits.upper - x, a_max, dt))
    if math.isfinite(positive_acceleration_max):
        # taut cap; never forces a speed-up in the negative direction
        v_cap = max(v + positive_acceleration_max * dt, min(v, 0.0))
        if v_cap >= v_lo:
            v_hi = min(v_hi, v_cap)
    v_new = min(max(v_des, v_lo), v_hi) if v_lo <= v_hi else v_lo
    x_new = min(max(x + v_new * dt, limits.lower), limits.upper)
    return x_new, (x_new - x) / dt
