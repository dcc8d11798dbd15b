"""The robot's own sensors for the gait: a downward rangefinder and a leg load cell per hemi.

DESIGN.md section 3, "What controllers may read". Each hemi body carries

* a rangefinder looking along the body's ``-z`` axis (``RANGE_AXIS_BASE``): it
  reads the distance along that ray to the ground (the plane ``z = 0``, or the
  :class:`~splitter_model.terrain.Terrain`: :func:`terrain_range_m`), ``+inf`` when the
  ray meets no ground within ``RANGE_MAX_M`` (pointing up or sideways: REP 117's
  "no return") and ``-inf`` below ``RANGE_MIN_M``;
* a load cell in its legs: the force its legs push with (the stance force and a
  jump's thrust), base frame. A body or limb touching the ground is not seen by it.

The simulator reads them from its state; the gait phase manager turns them back into
heights with the same geometry (:func:`hemi_height_from_range`). ROS-free.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from splitter_model.terrain import Terrain

RANGE_AXIS_BASE = (0.0, 0.0, -1.0)  # the rangefinders' ray, base frame
RANGE_MIN_M = 0.02  # [m] closer reads -inf
RANGE_MAX_M = 20.0  # [m] farther (or no ground on the ray) reads +inf
RANGE_FIELD_OF_VIEW_RAD = 0.05  # [rad] the beam's full angle (a narrow laser)
RAY_STEP_M = 0.02  # [m] the ray is sampled this often over a terrain (thinner steps missed)
RAY_TOLERANCE_M = 1.0e-6  # [m] a terrain return is refined to this


def _ray_down_component(rotation_world_base: ArrayLike) -> float:
    """World z of the ray's direction (negative: it points down)."""
    rot = np.asarray(rotation_world_base, dtype=float).reshape(3, 3)
    return float(rot[2] @ np.asarray(RANGE_AXIS_BASE))


def downward_range_m(hemi_height_m: float, rotation_world_base: ArrayLike) -> float:
    """What a hemi's rangefinder reads [m], its body ``hemi_height_m`` above the ground."""
    down = _ray_down_component(rotation_world_base)
    if down >= 0.0:
        return math.inf
    distance = float(hemi_height_m) / -down
    if distance < RANGE_MIN_M:
        return -math.inf
    return distance if distance <= RANGE_MAX_M else math.inf


def terrain_range_m(terrain: Terrain, origin_m: ArrayLike, rotation_world_base: ArrayLike) -> float:
    """What a hemi's rangefinder at ``origin_m`` (world [m]) reads over ``terrain`` [m].

    On level ground exactly :func:`downward_range_m`. Else the first point of the ray
    below the ground's surface (:meth:`Terrain.height_m`), found in steps of
    ``RAY_STEP_M`` and refined by bisection to ``RAY_TOLERANCE_M``.
    """
    origin = np.asarray(origin_m, dtype=float)
    if terrain.flat:
        return downward_range_m(float(origin[2]), rotation_world_base)
    rot = np.asarray(rotation_world_base, dtype=float).reshape(3, 3)
    ray = rot @ np.asarray(RANGE_AXIS_BASE)

    def below(t: float) -> bool:
        p = origin + t * ray
        return bool(p[2] < terrain.height_m(float(p[0]), float(p[1])))

    if below(0.0):
        return -math.inf
    samples = np.arange(RAY_STEP_M, RANGE_MAX_M + RAY_STEP_M, RAY_STEP_M)
    points = origin + samples[:, None] * ray
    ground = terrain.heights_m(points[:, :2])
    hits = np.flatnonzero(points[:, 2] < ground)
    if hits.size == 0:
        return math.inf
    hi = float(samples[hits[0]])
    lo = hi - RAY_STEP_M
    while hi - lo > RAY_TOLERANCE_M:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if below(mid) else (mid, hi)
    distance = 0.5 * (lo + hi)
    if distance < RANGE_MIN_M:
        return -math.inf
    return distance if distance <= RANGE_MAX_M else math.inf


def hemi_height_from_range(range_m: float, rotation_world_base: ArrayLike) -> float | None:
    """The hemi body's height above the ground [m] from its rangefinder; None without a
    return (an infinite reading, or a ray that does not point down)."""
    down = _ray_down_component(rotation_world_base)
    if not math.isfinite(range_m) or down >= 0.0:
        return None
    return float(range_m) * -down
