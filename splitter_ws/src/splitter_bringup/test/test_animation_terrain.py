"""The views of a run draw its terrain (a sloped base plane with steps).

* Animation: the frames' ground is the run's terrain (:func:`flight_frames`); the
  ground's wireframe follows :meth:`Ground.height_at` (the slope, a step's top and its
  walls), the step edges are the boxes' twelve edges; a few frames over a sloped
  terrain with a step render and write a gif, and the ground shows in the picture.
* Trajectory and gait figures: drawn with the ground under the path.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from splitter_bringup.analysis.flight_frames import flight_frames
from splitter_bringup.analysis.series import RunSeries
from splitter_bringup.figures.animation import (
    GRID_SUBDIVISIONS,
    MAX_GROUND_VERTICES,
    _Scene,
    grid_spacing_m,
    ground_grid_lines,
    step_edge_lines,
)
from splitter_bringup.figures.flight_animation import write_animation
from splitter_bringup.figures.trajectory import ground_under_path_m
from splitter_model.kinematics import joint_positions_from_radii
from splitter_model.model import RobotModel
from splitter_model.terrain import FLAT, Step, Terrain
from splitter_sim.core.scene import Ground

MODEL = RobotModel()
DT = 0.005  # [s]
FPS = 10.0  # [1/s]: 3 frames over 0.2 s
SIZE_PX = (160, 120)  # [px] small: the test is about drawing the ground, not pictures
STEP = Step(0.5, 2.0, -1.0, 1.0, 0.4)
TERRAIN = Terrain(12.0, 20.0, (STEP,))


def _series(duration_s: float = 0.2, gravity_m_s2: float = 1.62) -> RunSeries:
    """A hop along x over the terrain: 1.5 m above the ground, tumbling slowly."""
    t = np.arange(0.0, duration_s + 1e-9, DT)
    n = len(t)
    position = np.zeros((n, 3))
    position[:, 0] = 4.0 * t
    position[:, 2] = [TERRAIN.height_m(x, 0.0) + 1.5 for x in position[:, 0]]
    half = 0.25 * t
    q = np.column_stack([np.cos(half), np.zeros(n), np.sin(half), np.zeros(n)])
    w = np.tile([0.0, 0.5, 0.0], (n, 1))
    inertia = np.tile([1.0, 140.0, 140.0], (n, 1))
    joints = np.tile(joint_positions_from_radii(MODEL, (2.8, 0.2, 0.2)), (n, 1))
    velocity = np.tile([4.0, 0.0, 0.0], (n, 1))
    return RunSeries(
        t, w, q, inertia, inertia, np.tile([2.8, 0.2, 0.2], (n, 1)), position, velocity,
        joints, gravity_m_s2, gait_phase=["IN_FLIGHT"] * n,
    )  # fmt: skip


def test_the_frames_stand_on_the_run_terrain() -> None:
    frames = flight_frames(_series(), FPS, terrain=TERRAIN)
    assert len(frames) == 3
    assert all(s.ground == Ground(terrain=TERRAIN) for s in frames.scenes)
    assert flight_frames(_series(), FPS).scenes[0].ground == Ground()  # default: level
    assert flight_frames(_series(gravity_m_s2=0.0), FPS, terrain=TERRAIN).scenes[0].ground is None


def test_the_wireframe_follows_the_slope_and_the_step() -> None:
    ground = Ground(terrain=TERRAIN)
    spacing = 0.5  # [m]
    lines = ground_grid_lines(ground, (-3.0, 4.0), (-2.0, 2.0), spacing)
    assert len(lines) == 9 + 15  # constant y every 0.5 m over [-2, 2], constant x over [-3, 4]
    segments = np.concatenate([np.stack([line[:-1], line[1:]], axis=1) for line in lines])
    points = np.concatenate(lines)
    # every vertex is on the ground
    heights = np.array([ground.height_at(x, y) for x, y, _ in points])
    np.testing.assert_allclose(points[:, 2], heights, atol=1e-12)
    # the slope shows: far up the rise the grid is higher than far down
    assert points[points[:, 0] > 3.9, 2].mean() - points[points[:, 0] < -2.9, 2].mean() > 1.0
    # a vertex at least every spacing / GRID_SUBDIVISIONS (the view clips vertex by vertex)
    horizontal = np.linalg.norm(segments[:, 1, :2] - segments[:, 0, :2], axis=1)
    assert horizontal.max() <= spacing / GRID_SUBDIVISIONS + 1e-9
    # the step's walls: near-vertical segments rising by the step's height
    rise = segments[:, 1, 2] - segments[:, 0, 2]
    walls = (horizontal < 1e-5) & (np.abs(rise) > 0.3)
    assert walls.sum() >= 4
    np.testing.assert_allclose(np.abs(rise[walls]), STEP.height_m, atol=1e-5)
    # on top of the step: the base plane plus its height
    on_top = (np.abs(points[:, 0] - 1.0) < 1e-9) & (np.abs(points[:, 1]) < 0.9)
    assert on_top.any()
    for x, y, z in points[on_top]:
        assert z == pytest.approx(TERRAIN.base_height_m(x, y) + STEP.height_m)
    # a long flight: the grid gets coarser, not heavier
    huge = ground_grid_lines(ground, (-500.0, 500.0), (-50.0, 50.0), spacing)
    assert sum(len(line) for line in huge) <= 1.2 * MAX_GROUND_VERTICES
    assert grid_spacing_m(3.3) == 1.0 and grid_spacing_m(0.3) == 0.1


def test_the_step_edges_are_its_box() -> None:
    ground = Ground(terrain=TERRAIN)
    edges = step_edge_lines(ground, 100.0)
    assert len(edges) == 12 and all(edge.shape == (2, 3) for edge in edges)
    ends = np.concatenate(edges)
    for x in (STEP.x_min_m, STEP.x_max_m):
        for y in (STEP.y_min_m, STEP.y_max_m):
            base = TERRAIN.base_height_m(x, y)
            at = ends[(ends[:, 0] == x) & (ends[:, 1] == y), 2]
            assert set(np.round(at, 12)) == {round(base, 12), round(base + STEP.height_m, 12)}
    assert sum(len(edge) for edge in step_edge_lines(ground, 0.25)) > 24  # for the clipping
    assert step_edge_lines(Ground(), 0.25) == []


def test_frames_over_a_sloped_terrain_with_a_step_render(tmp_path: Path) -> None:
    info = write_animation(
        _series(), tmp_path / "flight.gif", "terrain", fps=FPS, size_px=SIZE_PX, terrain=TERRAIN
    )
    assert info.frames == 3 and info.path.stat().st_size > 0
    # the ground shows: the same frame without a ground differs
    with_ground = _Scene(flight_frames(_series(), FPS, terrain=TERRAIN), "", SIZE_PX)
    without = _Scene(flight_frames(_series(gravity_m_s2=0.0), FPS), "", SIZE_PX)
    try:
        for k in range(3):
            a, b = with_ground.draw(k), without.draw(k)
            assert a.shape == (SIZE_PX[1], SIZE_PX[0], 3)
            assert np.count_nonzero(np.any(a != b, axis=2)) > 50
    finally:
        with_ground.close()
        without.close()


def test_the_trajectory_and_gait_figures_draw_the_ground(tmp_path: Path) -> None:
    from splitter_bringup.figures.plots import plot_gait
    from splitter_bringup.figures.trajectory import plot_trajectory

    series = _series(0.6)
    ground = ground_under_path_m(TERRAIN, series.position_m)
    x = series.position_m[:, 0]
    expected = [TERRAIN.height_m(v, 0.0) for v in x]
    np.testing.assert_allclose(ground, expected)
    assert ground.max() - ground.min() > STEP.height_m  # the step and the slope
    assert np.all(ground_under_path_m(FLAT, series.position_m) == 0.0)
    for terrain in (TERRAIN, FLAT):
        name = "slope" if terrain is TERRAIN else "flat"
        assert plot_trajectory(series, tmp_path / f"{name}.png", "t", terrain=terrain).exists()
        gait = plot_gait(series, tmp_path / f"{name}_gait.png", "g", 200.0, terrain=terrain)
        assert gait.exists()


def test_a_bag_says_which_ground_its_simulator_flew_over(tmp_path: Path) -> None:
    from splitter_bag import BagWriter
    from splitter_bag.core.node_parameters import MEDIA_TYPE, attachment_name, parameter_file_text
    from splitter_bringup.cli.bag_figures import SIMULATOR_NODE, bag_terrain
    from splitter_msgs_py import names

    def bag(folder: str, params: dict | None) -> Path:
        bag_dir = tmp_path / folder / "bag"
        with BagWriter(bag_dir) as writer:
            if params is not None:
                text = parameter_file_text(SIMULATOR_NODE, params)
                writer.add_attachment(attachment_name(SIMULATOR_NODE), text.encode(), MEDIA_TYPE)
            writer.add_topic(names.ODOM, names.TOPIC_TYPES[names.ODOM])
        return bag_dir

    ground = {
        "ground_slope_deg": TERRAIN.slope_deg,
        "ground_slope_azimuth_deg": TERRAIN.slope_azimuth_deg,
        "ground_steps_m": list(TERRAIN.steps_flat()),
        "dt_s": 0.005,
    }
    assert bag_terrain(bag("sloped", ground)) == TERRAIN
    assert bag_terrain(bag("level", {"dt_s": 0.005})) == FLAT  # defaults: level
    bare = bag("bare", None)
    assert bag_terrain(bare) == FLAT
    # the run folder's parameter file beside the bag
    (bare.parent / "params").mkdir()
    (bare.parent / "params" / f"{SIMULATOR_NODE}.yaml").write_text(
        parameter_file_text(SIMULATOR_NODE, ground), encoding="utf-8"
    )
    assert bag_terrain(bare) == TERRAIN
    # unreadable ground parameters: drawn level (with a warning), not a failure
    assert bag_terrain(bag("bad", {**ground, "ground_steps_m": [1.0, 2.0]})) == FLAT
