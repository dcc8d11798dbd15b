"""The robot's own sensors for the gait: a downward rangefinder and a leg load cell per hemi.

DESIGN.md section 3, "What controllers may read". Each hemi body carries

* a rangefinder looking along the body's ``-z`` axis (``RANGE_AXIS_BASE``): it
  reads the distance along that ray to the ground plane ``z = 0``, ``+inf`` when the
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

RANGE_AXIS_BASE = (0.0, 0.0, -1.0)  # the rangefinders' ray, base frame
RANGE_MIN_M = 0.02  # [m] closer reads -inf
RANGE_MAX_M = 20.0  # [m] farther (or no ground on the ray) reads +inf
RANGE_FIELD_OF_VIEW_RAD = 0.05  # [rad] the beam's full angle (a narrow laser)


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


def hemi_height_from_range(range_m: float, rotation_world_base: ArrayLike) -> float | None:
    """The hemi body's height above the ground [m] from its rangefinder; None without a
    return (an infinite reading, or a ray that does not point down)."""
    down = _ray_down_component(rotation_world_base)
    if not math.isfinite(range_m) or down >= 0.0:
        return None
    return float(range_m) * -down
