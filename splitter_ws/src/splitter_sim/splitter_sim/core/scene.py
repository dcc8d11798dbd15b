"""The 3D scene of a flight in the world frame: masses, tether, limbs and arrows (ROS-free).

Shared by the Foxglove bridge (:mod:`splitter_bringup.foxglove_bridge_node`, which
turns it into ``visualization_msgs/Marker`` arrows) and the animation
(:mod:`splitter_bringup.core.animation`).

* Mass positions: the simulator's own geometry (:class:`splitter_sim.core.shape.ShapeKinematics`)
  from the 25 joint positions, about the centre of mass, rotated and moved by the
  odometry pose. Index 0 is hemi a's body, 1..4 its limb tips (``names.LIMB_AXES``
  order), 5 hemi b's body, 6..9 its limb tips, as in the simulator's markers.
* Arrows: the body axes (x red, y green, z blue), the world angular momentum
  ``H = R diag(I) w`` (principal inertia as published on ``/splitter/inertia``; the
  products of inertia of the symmetric shapes are left out) and each hemi's ground
  contact force, drawn from the hemi's lowest mass.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.model import RobotModel
from splitter_sim.core.shape import BODY_INDICES, ShapeKinematics

N_MASSES = 10
HEMI_MASSES = ((0, 1, 2, 3, 4), (5, 6, 7, 8, 9))  # mass indices of hemi a and hemi b
# (body, tip) mass index pairs of the eight limbs
LIMB_SEGMENTS = tuple((body, tip) for body in BODY_INDICES for tip in range(body + 1, body + 5))
AXIS_LENGTH_M = 0.6  # [m] drawn length of each body axis
MOMENTUM_SCALE_M = 0.01  # [m per kg m^2/s] drawn length of the angular momentum
MOMENTUM_MAX_LENGTH_M = 3.0  # [m] longest drawn angular momentum arrow
FORCE_SCALE_M = 0.01  # [m per N] drawn length of a contact force
MIN_FORCE_N = 1e-3  # [N] smaller contact forces are not drawn (zero-length arrow)
AXIS_COLORS = ((0.9, 0.1, 0.1, 1.0), (0.1, 0.8, 0.1, 1.0), (0.1, 0.3, 0.9, 1.0))  # RGBA
MOMENTUM_COLOR = (0.6, 0.1, 0.8, 1.0)  # RGBA
CONTACT_COLOR = (1.0, 0.8, 0.0, 1.0)  # RGBA


@dataclass(frozen=True)
class Arrow:
    """One arrow of the scene, world frame [m]."""

    name: str  # "axis_x", "axis_y", "axis_z", "angular_momentum", "contact_a", "contact_b"
    start: NDArray[np.float64]  # (3,) [m]
    end: NDArray[np.float64]  # (3,) [m]
    color: tuple[float, float, float, float]  # RGBA in [0, 1]

    @property
    def length_m(self) -> float:
        return float(np.linalg.norm(self.end - self.start))


def rotation_matrix(orientation_wxyz: ArrayLike) -> NDArray[np.float64]:
    """Rotation (3, 3) body -> world of a quaternion (w, x, y, z); normalised first."""
    q = np.asarray(orientation_wxyz, dtype=float)
    norm = float(np.linalg.norm(q))
    if not np.isfinite(norm) or norm < 1e-12:
        raise ValueError(f"orientation {q} is not a rotation")
    w, x, y, z = q / norm
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


class SceneGeometry:
    """Mass positions of the robot from joint positions and pose (one model, reused)."""

    def __init__(self, model: RobotModel | None = None) -> None:
        self.model = model or RobotModel()
        self._shape = ShapeKinematics(self.model)

    def body_positions(self, joint_positions: ArrayLike) -> NDArray[np.float64]:
        """(10, 3) mass positions about the centre of mass, body frame [m]."""
        q = [float(v) for v in np.asarray(joint_positions, dtype=float).reshape(-1)]
        if len(q) != 25:
            raise ValueError(f"expected 25 joint positions, got {len(q)}")
        return self._shape.evaluate(q).positions()

    def world_positions(
        self, position_m: ArrayLike, orientation_wxyz: ArrayLike, joint_positions: ArrayLike
    ) -> NDArray[np.float64]:
        """(10, 3) mass positions in the world frame [m]."""
        rot = rotation_matrix(orientation_wxyz)
        return np.asarray(position_m, dtype=float) + self.body_positions(joint_positions) @ rot.T


def body_axes(position_m: ArrayLike, orientation_wxyz: ArrayLike) -> list[Arrow]:
    """The base frame's x, y, z axes at the centre of mass."""
    origin = np.asarray(position_m, dtype=float)
    rot = rotation_matrix(orientation_wxyz)
    return [
        Arrow(f"axis_{name}", origin, origin + AXIS_LENGTH_M * rot[:, i], AXIS_COLORS[i])
        for i, name in enumerate("xyz")
    ]


def angular_momentum_world(
    orientation_wxyz: ArrayLike,
    principal_inertia_kg_m2: ArrayLike,
    angular_velocity_rad_s: ArrayLike,
) -> NDArray[np.float64]:
    """``H = R diag(I) w`` [kg m^2/s] (body-frame angular velocity)."""
    inertia = np.asarray(principal_inertia_kg_m2, dtype=float)
    w = np.asarray(angular_velocity_rad_s, dtype=float)
    return rotation_matrix(orientation_wxyz) @ (inertia * w)


def momentum_arrow(position_m: ArrayLike, momentum_world: ArrayLike) -> Arrow:
    """The angular momentum from the centre of mass, scaled and capped in length."""
    origin = np.asarray(position_m, dtype=float)
    h = np.asarray(momentum_world, dtype=float) * MOMENTUM_SCALE_M
    length = float(np.linalg.norm(h))
    if length > MOMENTUM_MAX_LENGTH_M:
        h *= MOMENTUM_MAX_LENGTH_M / length
    return Arrow("angular_momentum", origin, origin + h, MOMENTUM_COLOR)


def contact_arrows(mass_positions_world: ArrayLike, contact_forces_n: ArrayLike) -> list[Arrow]:
    """Each hemi's contact force (world) from its lowest mass; forces below MIN_FORCE_N skipped."""
    positions = np.asarray(mass_positions_world, dtype=float).reshape(N_MASSES, 3)
    forces = np.asarray(contact_forces_n, dtype=float).reshape(2, 3)
    out = []
    for hemi, (label, indices) in enumerate(zip("ab", HEMI_MASSES, strict=True)):
        if not np.all(np.isfinite(forces[hemi])) or np.linalg.norm(forces[hemi]) < MIN_FORCE_N:
            continue
        lowest = positions[list(indices)][np.argmin(positions[list(indices), 2])]
        out.append(
            Arrow(f"contact_{label}", lowest, lowest + FORCE_SCALE_M * forces[hemi], CONTACT_COLOR)
        )
    return out


def scene_arrows(
    position_m: ArrayLike,
    orientation_wxyz: ArrayLike,
    principal_inertia_kg_m2: ArrayLike,
    angular_velocity_rad_s: ArrayLike,
    *,
    mass_positions_world: ArrayLike | None = None,
    contact_forces_n: ArrayLike | None = None,
) -> list[Arrow]:
    """Body axes, angular momentum and (with masses and forces given) contact forces."""
    arrows = body_axes(position_m, orientation_wxyz)
    h = angular_momentum_world(orientation_wxyz, principal_inertia_kg_m2, angular_velocity_rad_s)
    arrows.append(momentum_arrow(position_m, h))
    if mass_positions_world is not None and contact_forces_n is not None:
        arrows += contact_arrows(mass_positions_world, contact_forces_n)
    return arrows
