"""The ground the robot lands on: a plane that may slope, with raised boxes (steps, rocks).

ROS-free, numpy-only; one description shared by the simulator (contact and legs),
the gait manager (height above the ground under each hemi), the landing judge
(tilts from the ground normal, body and tether contact) and the drawings.

* The **base plane** passes through the world origin and rises with slope ``theta``
  towards the azimuth ``alpha`` (from world x, about world z): its upward normal is
  ``n = (-sin theta cos alpha, -sin theta sin alpha, cos theta)`` and its height
  ``z = tan theta (x cos alpha + y sin alpha)``. The slope is at most
  :data:`SLOPE_MAX_DEG` (a foot of friction coefficient ``mu`` holds on a slope up to
  ``atan(mu)``: 38.7 deg for the default 0.8; the scenario language stops below).
* A **step** is a box over an axis-aligned rectangle of the world's x-y plane,
  raised ``height_m`` (vertically) above the base plane: its top is parallel to
  the base plane, its four walls are vertical.

Contact with this ground is a plane per point (:meth:`Terrain.contact_plane`): the
base plane, the top of the highest step whose footprint holds the point, or, for a
point inside a step deeper than it is from one of the step's walls, that wall (the
face it entered by, as a box contact takes the face of least penetration). A plane
is ``(nx, ny, nz, d)``: the signed distance of a point ``p`` to it is ``n . p - d``
(positive outside the ground).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

SLOPE_MAX_DEG = 30.0  # [deg] steepest base plane the scenario language accepts
STEP_HEIGHT_MAX_M = 2.0  # [m] tallest step (five times the legs' stroke)
STEP_FIELDS = 5  # x_min, x_max, y_min, y_max [m], height [m]: one step as flat floats

Plane = tuple[float, float, float, float]  # (nx, ny, nz, d): n . p - d is the distance [m]
FLAT_PLANE: Plane = (0.0, 0.0, 1.0, 0.0)


@dataclass(frozen=True)
class Step:
    """A box raised ``height_m`` over the rectangle [x_min, x_max] x [y_min, y_max] [m]."""

    x_min_m: float
    x_max_m: float
    y_min_m: float
    y_max_m: float
    height_m: float

    def __post_init__(self) -> None:
        for name in ("x_min_m", "x_max_m", "y_min_m", "y_max_m", "height_m"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value)):
                raise ValueError(f"{name}: must be a finite number, got {value!r}")
        if not self.x_max_m > self.x_min_m:
            raise ValueError(f"x_m: x_max {self.x_max_m} must exceed x_min {self.x_min_m}")
        if not self.y_max_m > self.y_min_m:
            raise ValueError(f"y_m: y_max {self.y_max_m} must exceed y_min {self.y_min_m}")
        if not 0.0 < self.height_m <= STEP_HEIGHT_MAX_M:
            raise ValueError(
                f"height_m: must be in (0, {STEP_HEIGHT_MAX_M}] m, got {self.height_m!r}"
            )

    def holds(self, x_m: float, y_m: float) -> bool:
        """Whether the footprint holds the point (x, y) [m] (edges included)."""
        return self.x_min_m <= x_m <= self.x_max_m and self.y_min_m <= y_m <= self.y_max_m

    def footprint_distance_m(self, x_m: float, y_m: float) -> float:
        """Horizontal distance [m] from (x, y) to the footprint (0 inside)."""
        dx = max(self.x_min_m - x_m, 0.0, x_m - self.x_max_m)
        dy = max(self.y_min_m - y_m, 0.0, y_m - self.y_max_m)
        return math.hypot(dx, dy)

    def as_floats(self) -> tuple[float, ...]:
        return (self.x_min_m, self.x_max_m, self.y_min_m, self.y_max_m, self.height_m)


@dataclass(frozen=True)
class Terrain:
    """A base plane of ``slope_deg`` rising towards ``slope_azimuth_deg``, and ``steps``."""

    slope_deg: float = 0.0  # [deg] in [0, SLOPE_MAX_DEG]
    slope_azimuth_deg: float = 0.0  # [deg] direction of the rise, from world x about z
    steps: tuple[Step, ...] = ()

    def __post_init__(self) -> None:
        slope = self.slope_deg
        if not (isinstance(slope, int | float) and math.isfinite(slope)):
            raise ValueError(f"slope_deg: must be a finite number, got {slope!r}")
        if not 0.0 <= slope <= SLOPE_MAX_DEG:
            raise ValueError(f"slope_deg: must be in [0, {SLOPE_MAX_DEG}] deg, got {slope!r}")
        azimuth = self.slope_azimuth_deg
        if not (isinstance(azimuth, int | float) and math.isfinite(azimuth)):
            raise ValueError(f"slope_azimuth_deg: must be a finite number, got {azimuth!r}")
        for step in self.steps:
            if not isinstance(step, Step):
                raise ValueError(f"steps: expected Step, got {step!r}")
        theta, alpha = math.radians(slope), math.radians(azimuth)
        normal = (
            -math.sin(theta) * math.cos(alpha),
            -math.sin(theta) * math.sin(alpha),
            math.cos(theta),
        )
        if slope == 0.0:
            normal = (0.0, 0.0, 1.0)
        object.__setattr__(self, "_normal", normal)
        rise = (math.tan(theta) * math.cos(alpha), math.tan(theta) * math.sin(alpha))
        object.__setattr__(self, "_rise", rise)

    # --- construction from flat parameters ---------------------------------------
    @classmethod
    def from_parameters(
        cls, slope_deg: float, slope_azimuth_deg: float, steps_flat: Sequence[float]
    ) -> Terrain:
        """From the simulator's parameters: steps as :data:`STEP_FIELDS` floats each."""
        values = [float(v) for v in steps_flat]
        if len(values) % STEP_FIELDS:
            raise ValueError(
                f"ground_steps_m: expected {STEP_FIELDS} values per step "
                f"(x_min, x_max, y_min, y_max, height), got {len(values)} values"
            )
        steps = tuple(
            Step(*values[i : i + STEP_FIELDS]) for i in range(0, len(values), STEP_FIELDS)
        )
        return cls(float(slope_deg), float(slope_azimuth_deg), steps)

    def steps_flat(self) -> tuple[float, ...]:
        """The steps as :data:`STEP_FIELDS` floats each (:meth:`from_parameters`)."""
        return tuple(v for step in self.steps for v in step.as_floats())

    # --- geometry ----------------------------------------------------------------
    @property
    def flat(self) -> bool:
        """The plane z = 0 (no slope, no step)."""
        return self.slope_deg == 0.0 and not self.steps

    @property
    def normal(self) -> tuple[float, float, float]:
        """Upward unit normal of the base plane and of every step's top."""
        return self._normal  # type: ignore[attr-defined]

    def base_height_m(self, x_m: float, y_m: float) -> float:
        """Height [m] of the base plane at (x, y)."""
        rx, ry = self._rise  # type: ignore[attr-defined]
        return rx * x_m + ry * y_m

    def step_height_m(self, x_m: float, y_m: float) -> float:
        """Height [m] of the highest step whose footprint holds (x, y) (0: none)."""
        return max((s.height_m for s in self.steps if s.holds(x_m, y_m)), default=0.0)

    def height_m(self, x_m: float, y_m: float) -> float:
        """Height [m] of the ground's surface at (x, y): base plane plus the step there."""
        if self.flat:
            return 0.0
        return self.base_height_m(x_m, y_m) + self.step_height_m(x_m, y_m)

    def heights_m(self, xy_m: ArrayLike) -> NDArray[np.float64]:
        """:meth:`height_m` of every point (rows x, y) [m], vectorised."""
        xy = np.atleast_2d(np.asarray(xy_m, dtype=float))
        x, y = xy[:, 0], xy[:, 1]
        if self.flat:
            return np.zeros(len(xy))
        rx, ry = self._rise  # type: ignore[attr-defined]
        step = np.zeros(len(xy))
        for s in self.steps:
            inside = (x >= s.x_min_m) & (x <= s.x_max_m) & (y >= s.y_min_m) & (y <= s.y_max_m)
            step = np.where(inside, np.maximum(step, s.height_m), step)
        return rx * x + ry * y + step

    def highest_within_m(self, x_m: float, y_m: float, radius_m: float) -> float:
        """An upper bound [m] of the ground's height within ``radius_m`` of (x, y)."""
        if self.flat:
            return 0.0
        rx, ry = self._rise  # type: ignore[attr-defined]
        step = max(
            (s.height_m for s in self.steps if s.footprint_distance_m(x_m, y_m) <= radius_m),
            default=0.0,
        )
        return self.base_height_m(x_m, y_m) + math.hypot(rx, ry) * radius_m + step

    def contact_plane(self, x_m: float, y_m: float, z_m: float) -> Plane:
        """The plane a point at (x, y, z) [m] touches (module docstring)."""
        if self.flat:
            return FLAT_PLANE
        nx, ny, nz = self._normal  # type: ignore[attr-defined]
        top, box = 0.0, None
        for step in self.steps:
            if step.height_m > top and step.holds(x_m, y_m):
                top, box = step.height_m, step
        d = nz * top  # the top is the base plane raised vertically by ``top``
        if box is None:
            return (nx, ny, nz, d)
        depth = d - (nx * x_m + ny * y_m + nz * z_m)  # below the top [m]
        walls = (
            (x_m - box.x_min_m, (-1.0, 0.0, 0.0, -box.x_min_m)),
            (box.x_max_m - x_m, (1.0, 0.0, 0.0, box.x_max_m)),
            (y_m - box.y_min_m, (0.0, -1.0, 0.0, -box.y_min_m)),
            (box.y_max_m - y_m, (0.0, 1.0, 0.0, box.y_max_m)),
        )
        inside, wall = min(walls, key=lambda item: item[0])
        if depth > inside:  # nearer a wall than the top: it came in through the wall
            return wall
        return (nx, ny, nz, d)

    def contact_planes(self, points_m: NDArray[np.float64] | Sequence) -> list[Plane]:
        """:meth:`contact_plane` of every point (rows x, y, z) [m]."""
        if self.flat:
            return [FLAT_PLANE] * len(points_m)
        return [self.contact_plane(float(p[0]), float(p[1]), float(p[2])) for p in points_m]

    def signed_distance_m(self, points_m: ArrayLike) -> NDArray[np.float64]:
        """Signed distance [m] of each point (rows x, y, z) to the ground it touches."""
        points = np.atleast_2d(np.asarray(points_m, dtype=float))
        if self.flat:
            return points[:, 2].copy()
        planes = np.array(self.contact_planes(points))
        return np.einsum("ij,ij->i", planes[:, :3], points) - planes[:, 3]

    def segment_clearance_m(self, start_m: ArrayLike, end_m: ArrayLike, samples: int = 33) -> float:
        """Smallest signed distance [m] to the ground along the segment (``samples`` points)."""
        a, b = np.asarray(start_m, dtype=float), np.asarray(end_m, dtype=float)
        s = np.linspace(0.0, 1.0, samples)[:, None]
        return float(self.signed_distance_m(a + s * (b - a)).min())

    def ground_frame(self) -> NDArray[np.float64]:
        """Rotation (3, 3) world <- ground: its z column is :attr:`normal`, its x column
        world x projected on the base plane (the identity on level ground)."""
        n = np.array(self.normal)
        if self.slope_deg == 0.0:
            return np.eye(3)
        x = np.array([1.0, 0.0, 0.0]) - n[0] * n
        if np.linalg.norm(x) < 1e-9:  # pragma: no cover - the slope is at most 30 deg
            x = np.array([0.0, 1.0, 0.0]) - n[1] * n
        x /= np.linalg.norm(x)
        return np.column_stack([x, np.cross(n, x), n])


FLAT = Terrain()
