"""The 3D scene of a flight in the world frame: masses, tether, limbs, contacts, ground (ROS-free).

:class:`Scene` is the scene as data, built by :func:`scene_from_pose` (from a
simulator state, :func:`scene_of_state`; from the graph's messages; from a recorded
series). The simulator publishes it (``/splitter/scene/masses`` beside the pose,
inertia, rate and contact wrench topics) and draws ``/splitter/markers`` from it;
the Foxglove bridge (:mod:`splitter_bringup.nodes.foxglove_bridge_node`) and the
animation (:mod:`splitter_bringup.figures.animation`) draw it too.

* Mass positions: the simulator's own geometry (:class:`splitter_sim.core.shape.ShapeKinematics`)
  from the 25 joint positions, about the centre of mass, rotated and moved by the
  odometry pose (:class:`SceneGeometry`). Index 0 is hemi a's body, 1..4 its limb tips
  (``names.LIMB_AXES`` order), 5 hemi b's body, 6..9 its limb tips.
* Arrows: the body axes (x red, y green, z blue), the world angular momentum
  ``H = R diag(I) w`` (principal inertia as published on ``/splitter/inertia``; the
  products of inertia of the symmetric shapes are left out) and each hemi's ground
  contact force, drawn from the hemi's lowest mass.
* Ground: :class:`Ground`, the terrain (:class:`splitter_model.terrain.Terrain`: a
  sloped base plane with steps) raised by ``height_m``; level z = 0 by default. The
  views draw it as boxes (:func:`ground_boxes`): a thin slab whose top is the base
  plane, around the robot, and one box per step (nothing on level ground z = 0, which
  RViz's and Foxglove's grids show).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from splitter_model.joints import N_JOINTS, TETHER_INDEX
from splitter_model.model import RobotModel
from splitter_model.rotations import quaternion_to_matrix as rotation_matrix
from splitter_model.terrain import FLAT, Terrain
from splitter_sim.core.shape import BODY_INDICES, ShapeKinematics
from splitter_sim.core.simulator import SimState

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
GROUND_HALF_SIDE_M = 8.0  # [m] half the side of the drawn base plane, about the robot
GROUND_THICKNESS_M = 0.02  # [m] thickness of the drawn base plane (its top is the plane)
GROUND_COLOR = (0.6, 0.6, 0.6, 0.5)  # RGBA
STEP_COLOR = (0.55, 0.45, 0.35, 0.9)  # RGBA
FAULT_COLOR = (0.95, 0.1, 0.1, 1.0)  # RGBA: a limb with a failed joint, a locked reel
BASE_PLANE = "base_plane"  # name of the base plane's box; a step's is "step_<index>"


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
    for hemi, label in enumerate("ab"):
        if not np.all(np.isfinite(forces[hemi])) or np.linalg.norm(forces[hemi]) < MIN_FORCE_N:
            continue
        lowest = lowest_mass(positions, hemi)
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
    h = angular_momentum_world(orientation_wxyz, principal_inertia_kg_m2, angular_velocity_rad_s)
    return _arrows(position_m, orientation_wxyz, h, mass_positions_world, contact_forces_n)


def _arrows(
    position_m: ArrayLike,
    orientation_wxyz: ArrayLike,
    momentum_world: ArrayLike,
    mass_positions_world: ArrayLike | None,
    contact_forces_n: ArrayLike | None,
) -> list[Arrow]:
    arrows = body_axes(position_m, orientation_wxyz)
    arrows.append(momentum_arrow(position_m, momentum_world))
    if mass_positions_world is not None and contact_forces_n is not None:
        arrows += contact_arrows(mass_positions_world, contact_forces_n)
    return arrows


@dataclass(frozen=True)
class Ground:
    """The ground, world frame: ``terrain`` (a sloped base plane with steps) raised by
    ``height_m``. ``Ground()`` is the level plane z = 0 (normal +z).

    The views draw the ground through this object (:meth:`height_at`, :func:`ground_boxes`).
    """

    height_m: float = 0.0  # [m] added to the terrain's height everywhere
    terrain: Terrain = FLAT

    @property
    def level(self) -> bool:
        """The plane z = 0: no slope, no step, no offset."""
        return self.height_m == 0.0 and self.terrain.flat

    def height_at(self, x_m: float, y_m: float) -> float:
        """Ground height under the world point (x, y) [m]: a step's top where there is one."""
        return self.height_m + self.terrain.height_m(x_m, y_m)


@dataclass(frozen=True)
class Box:
    """One box of the drawn ground, world frame: centre, sides along its own axes, orientation."""

    name: str  # BASE_PLANE or "step_<index>" (index in Terrain.steps)
    centre_m: NDArray[np.float64]  # (3,) [m]
    size_m: NDArray[np.float64]  # (3,) sides along the box's x, y, z axes [m]
    orientation_wxyz: NDArray[np.float64]  # (4,) world <- box (unit)
    color: tuple[float, float, float, float]  # RGBA in [0, 1]


def _frame_quaternion(frame: NDArray[np.float64]) -> NDArray[np.float64]:
    """(w, x, y, z) of the rotation matrix ``frame`` (w >= 0)."""
    q = Rotation.from_matrix(frame).as_quat(scalar_first=True)
    return q if q[0] >= 0.0 else -q


def ground_boxes(
    ground: Ground, around_m: ArrayLike, half_side_m: float = GROUND_HALF_SIDE_M
) -> tuple[Box, ...]:
    """The ground as boxes tilted with the slope (their z axis the terrain's normal).

    First the base plane: a slab ``GROUND_THICKNESS_M`` thick whose top is the base
    plane, ``2 half_side_m`` square, centred under ``around_m`` (x, y [m]: the robot).
    Then one box per step (name ``step_<i>``): its footprint, from the base plane up to
    its top, centred at the base plane's height under the footprint's centre plus half
    the step's height. A box's walls are perpendicular to the base plane, the step's
    are vertical: on a slope of ``theta`` they lean ``theta`` from each other. Level
    ground (:attr:`Ground.level`) gives no box; the names are the same on every call.
    """
    if ground.level:
        return ()
    terrain = ground.terrain
    frame = terrain.ground_frame()  # columns: box x, y, z axes in the world
    q = _frame_quaternion(frame)
    n = frame[:, 2]
    x, y = (float(v) for v in np.asarray(around_m, dtype=float).reshape(-1)[:2])
    on_plane = np.array([x, y, ground.height_m + terrain.base_height_m(x, y)])
    side = 2.0 * float(half_side_m)
    boxes = [
        Box(
            BASE_PLANE,
            on_plane - 0.5 * GROUND_THICKNESS_M * n,
            np.array([side, side, GROUND_THICKNESS_M]),
            q,
            GROUND_COLOR,
        )
    ]
    for i, step in enumerate(terrain.steps):
        cx = 0.5 * (step.x_min_m + step.x_max_m)
        cy = 0.5 * (step.y_min_m + step.y_max_m)
        cz = ground.height_m + terrain.base_height_m(cx, cy) + 0.5 * step.height_m
        # the footprint's sides along the box's axes (their world x, y parts span it);
        # the height: the top is the base plane raised vertically by height_m
        size = np.array(
            [
                (step.x_max_m - step.x_min_m) / frame[0, 0],
                (step.y_max_m - step.y_min_m) / frame[1, 1],
                step.height_m * n[2],
            ]
        )
        boxes.append(Box(f"step_{i}", np.array([cx, cy, cz]), size, q, STEP_COLOR))
    return tuple(boxes)


@dataclass(frozen=True)
class Scene:
    """The robot and its surroundings at one instant, world frame [m]: what every view draws.

    Built by :func:`scene_from_pose` (from a state, messages or a recorded series);
    the simulator node's markers, the Foxglove bridge and the animation draw it.
    """

    t_ns: int  # [ns] simulated time
    position_m: NDArray[np.float64]  # (3,) centre of mass [m]
    orientation_wxyz: NDArray[np.float64]  # (4,) world <- base (the hemis' frames too)
    mass_positions_m: NDArray[np.float64]  # (10, 3) lumped masses (module docstring order)
    angular_momentum_kg_m2_s: NDArray[np.float64]  # (3,) world, H = R diag(I) w [kg m^2/s]
    contact_forces_n: NDArray[np.float64] | None = None  # (2, 3) ground on hemi a, b [N]
    contact_torques_n_m: NDArray[np.float64] | None = None  # (2, 3) about each hemi body [N m]
    ground: Ground | None = None  # None: no ground (free flight)
    # limbs (LIMB_SEGMENTS order) with a failed joint, and the reel locked (ground truth)
    faulty_limbs: frozenset[int] = frozenset()
    reel_locked: bool = False

    @property
    def hemi_centres_m(self) -> NDArray[np.float64]:
        """(2, 3) hemi a and hemi b body positions [m]."""
        return self.mass_positions_m[list(BODY_INDICES)]

    @property
    def tether_m(self) -> NDArray[np.float64]:
        """(2, 3) the tether's ends: the two hemi bodies [m]."""
        return self.hemi_centres_m

    @property
    def limb_segments_m(self) -> NDArray[np.float64]:
        """(8, 2, 3) (body, tip) of each limb, in :data:`LIMB_SEGMENTS` order [m]."""
        return self.mass_positions_m[np.array(LIMB_SEGMENTS)]

    @property
    def contact_points_m(self) -> NDArray[np.float64]:
        """(2, 3) where each hemi meets the ground: its lowest mass [m]."""
        return np.array([lowest_mass(self.mass_positions_m, hemi) for hemi in (0, 1)])

    @property
    def arrows(self) -> tuple[Arrow, ...]:
        """Body axes, angular momentum and (when known) the contact forces."""
        return tuple(
            _arrows(
                self.position_m,
                self.orientation_wxyz,
                self.angular_momentum_kg_m2_s,
                self.mass_positions_m,
                self.contact_forces_n,
            )
        )


def lowest_mass(mass_positions_world: ArrayLike, hemi: int) -> NDArray[np.float64]:
    """(3,) the lowest of hemi ``hemi``'s five masses [m]."""
    positions = np.asarray(mass_positions_world, dtype=float).reshape(N_MASSES, 3)
    own = positions[list(HEMI_MASSES[hemi])]
    return own[np.argmin(own[:, 2])]


def _array(value: ArrayLike | None, shape: tuple[int, ...]) -> NDArray[np.float64] | None:
    if value is None:
        return None
    out = np.array(value, dtype=float).reshape(shape)
    out.flags.writeable = False
    return out


def scene_from_pose(
    t_ns: int,
    position_m: ArrayLike,
    orientation_wxyz: ArrayLike,
    *,
    mass_positions_world: ArrayLike,
    principal_inertia_kg_m2: ArrayLike,
    angular_velocity_rad_s: ArrayLike,
    contact_forces_n: ArrayLike | None = None,
    contact_torques_n_m: ArrayLike | None = None,
    ground: Ground | None = None,
    joint_fault: ArrayLike | None = None,
) -> Scene:
    """The scene of one instant: pose, masses, principal inertia, body rate, contacts;
    ``joint_fault`` (25, ``splitter_model.faults.FAULT_CODES``, 0 healthy) marks the
    limbs with a failed joint and a locked reel."""
    faults = np.zeros(N_JOINTS) if joint_fault is None else np.asarray(joint_fault).reshape(-1)
    h = angular_momentum_world(orientation_wxyz, principal_inertia_kg_m2, angular_velocity_rad_s)
    return Scene(
        t_ns=int(t_ns),
        position_m=_array(position_m, (3,)),
        orientation_wxyz=_array(orientation_wxyz, (4,)),
        mass_positions_m=_array(mass_positions_world, (N_MASSES, 3)),
        angular_momentum_kg_m2_s=_array(h, (3,)),
        contact_forces_n=_array(contact_forces_n, (2, 3)),
        contact_torques_n_m=_array(contact_torques_n_m, (2, 3)),
        ground=ground,
        faulty_limbs=frozenset(
            {int(j) // 3 for j in np.flatnonzero(faults[:TETHER_INDEX]).tolist()}
        ),
        reel_locked=bool(faults[TETHER_INDEX]),
    )


def scene_of_state(state: SimState, ground: Ground | None = None) -> Scene:
    """The scene of a simulator state (``ground``: the simulator's, None without contact)."""
    return scene_from_pose(
        state.t_ns,
        state.position_m,
        state.orientation_wxyz,
        mass_positions_world=state.mass_positions_world_m,
        principal_inertia_kg_m2=state.principal_inertia_kg_m2,
        angular_velocity_rad_s=state.angular_velocity_rad_s,
        contact_forces_n=state.contact_force_n,
        contact_torques_n_m=state.contact_torque_n_m,
        ground=ground,
        joint_fault=state.joint_fault,
    )
