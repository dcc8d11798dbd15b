"""The scene's ground follows the terrain, and the simulator's markers draw it.

* ``Ground(terrain=...)``: :meth:`Ground.height_at` is the terrain's height (slope,
  a step's top) plus ``height_m``; ``Ground()`` stays the level plane z = 0.
* ``/splitter/markers`` (:func:`splitter_sim.messages.scene_markers`): over a sloped
  terrain with two steps, a cube for the base plane and one per step, centred at the
  step's mid-height, oriented with the terrain's normal, same ids every message; level
  ground adds no marker.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from visualization_msgs.msg import Marker

from splitter_model.model import RobotModel
from splitter_model.rotations import quaternion_to_matrix
from splitter_model.terrain import Step, Terrain
from splitter_sim.core.scene import (
    BASE_PLANE,
    GROUND_THICKNESS_M,
    Ground,
    ground_boxes,
    scene_from_pose,
)
from splitter_sim.core.simulator import InitialState, SimConfig, Simulator
from splitter_sim.core.tick import SimulatorTick
from splitter_sim.messages import GROUND_NS, scene_markers

SLOPE_DEG = 10.0  # [deg]
AZIMUTH_DEG = 30.0  # [deg]
STEPS = (Step(2.0, 4.0, -1.0, 1.0, 0.3), Step(-3.0, -1.0, 0.5, 2.5, 0.5))
TERRAIN = Terrain(SLOPE_DEG, AZIMUTH_DEG, STEPS)


def _scene(ground: Ground | None, position=(0.5, -0.2, 3.0), t_ns: int = 7):
    masses = np.zeros((10, 3))
    masses[:, 0] = [position[0] + (2.8 if i < 5 else -2.8) for i in range(10)]
    masses[:, 1] = position[1]
    masses[:, 2] = [position[2] - 0.1 * (i % 5) for i in range(10)]
    return scene_from_pose(
        t_ns,
        position,
        [1.0, 0.0, 0.0, 0.0],
        mass_positions_world=masses,
        principal_inertia_kg_m2=[1.0, 140.0, 140.0],
        angular_velocity_rad_s=[0.0, 1.0, 0.0],
        contact_forces_n=[[0.0, 0.0, 0.0], [0.0, 0.0, 50.0]],
        ground=ground,
    )


def _orientation(marker: Marker) -> np.ndarray:
    o = marker.pose.orientation
    return np.array([o.w, o.x, o.y, o.z])


def test_ground_height_follows_the_slope_and_the_steps() -> None:
    ground = Ground(terrain=TERRAIN)
    theta, alpha = math.radians(SLOPE_DEG), math.radians(AZIMUTH_DEG)
    rise = math.tan(theta) * np.array([math.cos(alpha), math.sin(alpha)])
    # on the base plane: z = tan(theta) (x cos(alpha) + y sin(alpha))
    for x, y in [(0.0, 0.0), (10.0, -5.0), (-7.0, 3.0), (1.9, 0.0)]:
        assert ground.height_at(x, y) == pytest.approx(rise @ [x, y], abs=1e-12)
    assert ground.height_at(10.0, 0.0) > 1.0  # it does rise towards +x
    # on a step: the base plane under the point plus the step's height
    assert ground.height_at(3.0, 0.5) == pytest.approx(rise @ [3.0, 0.5] + 0.3, abs=1e-12)
    assert ground.height_at(-2.0, 1.0) == pytest.approx(rise @ [-2.0, 1.0] + 0.5, abs=1e-12)
    # height_m raises the whole terrain
    raised = Ground(height_m=0.25, terrain=TERRAIN)
    assert raised.height_at(3.0, 0.5) == pytest.approx(ground.height_at(3.0, 0.5) + 0.25)
    # Ground() is still the level plane z = 0, and a level step-free ground draws nothing
    assert Ground().height_at(3.0, 0.5) == 0.0 and Ground().level
    assert not ground.level and ground_boxes(Ground(), (0.0, 0.0)) == ()


def test_a_step_alone_on_level_ground() -> None:
    ground = Ground(terrain=Terrain(steps=(Step(0.0, 1.0, 0.0, 1.0, 0.4),)))
    assert ground.height_at(0.5, 0.5) == pytest.approx(0.4)
    assert ground.height_at(1.5, 0.5) == 0.0
    boxes = ground_boxes(ground, (0.0, 0.0))
    assert [b.name for b in boxes] == [BASE_PLANE, "step_0"]
    np.testing.assert_allclose(boxes[1].centre_m, [0.5, 0.5, 0.2])
    np.testing.assert_allclose(boxes[1].size_m, [1.0, 1.0, 0.4])
    np.testing.assert_allclose(boxes[1].orientation_wxyz, [1.0, 0.0, 0.0, 0.0])


def test_markers_draw_the_base_plane_and_one_cube_per_step() -> None:
    ground = Ground(terrain=TERRAIN)
    scene = _scene(ground)
    markers = [m for m in scene_markers(scene).markers if m.ns == GROUND_NS]
    assert [m.id for m in markers] == [0, 1, 2]
    assert all(m.type == Marker.CUBE and m.action == Marker.ADD for m in markers)
    normal = np.array(TERRAIN.normal)
    for m in markers:
        q = _orientation(m)
        assert np.all(np.isfinite(q)) and np.linalg.norm(q) == pytest.approx(1.0)
        # the cube's z axis is the terrain's normal (tilted with the slope)
        np.testing.assert_allclose(quaternion_to_matrix(q)[:, 2], normal, atol=1e-12)
        values = [m.pose.position.x, m.pose.position.y, m.pose.position.z]
        values += [m.scale.x, m.scale.y, m.scale.z]
        assert all(math.isfinite(v) for v in values) and min(values[3:]) > 0.0
        assert m.header.frame_id == "world"
    assert normal[2] < math.cos(math.radians(SLOPE_DEG)) + 1e-12  # really tilted
    # each step's cube: centred over its footprint at its mid-height above the base plane
    for step, m in zip(STEPS, markers[1:], strict=True):
        cx, cy = 0.5 * (step.x_min_m + step.x_max_m), 0.5 * (step.y_min_m + step.y_max_m)
        assert m.pose.position.x == pytest.approx(cx, abs=1e-12)
        assert m.pose.position.y == pytest.approx(cy, abs=1e-12)
        centre_z = TERRAIN.base_height_m(cx, cy) + 0.5 * step.height_m
        assert abs(m.pose.position.z - centre_z) < 1e-9
        # its top and bottom faces are the step's top and the base plane (vertically)
        assert m.scale.z == pytest.approx(step.height_m * normal[2])
        assert m.scale.x >= step.x_max_m - step.x_min_m
        assert m.scale.y >= step.y_max_m - step.y_min_m
    # the base plane: a thin slab under the robot whose top is the base plane
    plane = markers[0]
    assert plane.scale.z == pytest.approx(GROUND_THICKNESS_M)
    centre = np.array([plane.pose.position.x, plane.pose.position.y, plane.pose.position.z])
    top = centre + 0.5 * GROUND_THICKNESS_M * normal
    assert top[2] == pytest.approx(TERRAIN.base_height_m(top[0], top[1]), abs=1e-12)
    np.testing.assert_allclose(top[:2], scene.position_m[:2], atol=0.01)


def test_ground_marker_ids_are_stable_across_messages() -> None:
    ground = Ground(terrain=TERRAIN)
    first = scene_markers(_scene(ground, (0.5, -0.2, 3.0), 7))
    later = scene_markers(_scene(ground, (6.0, 1.5, 1.2), 5_000_007))
    assert [(m.ns, m.id, m.type) for m in first.markers] == [
        (m.ns, m.id, m.type) for m in later.markers
    ]
    moved = [m for m in later.markers if m.ns == GROUND_NS]
    assert moved[0].pose.position.x == pytest.approx(6.0, abs=0.01)  # the plane follows
    assert moved[1].pose.position.x == pytest.approx(3.0)  # the steps stay put


def test_level_ground_adds_no_marker() -> None:
    level = scene_markers(_scene(Ground())).markers
    nothing = scene_markers(_scene(None)).markers
    # 10 masses, the tether, the limbs and the arrows (3 axes, momentum, hemi b's force)
    assert len(level) == len(nothing) == 10 + 1 + 1 + 5
    assert not any(m.ns == GROUND_NS for m in level)
    assert [(m.ns, m.id) for m in level] == [(m.ns, m.id) for m in nothing]


def test_the_simulator_tick_grounds_its_scenes_on_the_configured_terrain() -> None:
    config = SimConfig(
        ground_slope_deg=SLOPE_DEG,
        ground_slope_azimuth_deg=AZIMUTH_DEG,
        ground_steps_m=TERRAIN.steps_flat(),
    )
    initial = InitialState(position_m=(0.0, 0.0, 5.0))  # above the steps
    tick = SimulatorTick(Simulator(RobotModel(), config, initial))
    assert tick.ground == Ground(terrain=TERRAIN)
    level = SimulatorTick(Simulator(RobotModel(), SimConfig(), initial))
    assert level.ground == Ground()
