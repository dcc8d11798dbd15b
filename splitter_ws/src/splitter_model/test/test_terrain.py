"""The ground's geometry: slope, steps, the plane a point touches, rays and clearances."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from splitter_model.sensors import downward_range_m, terrain_range_m
from splitter_model.terrain import FLAT, FLAT_PLANE, SLOPE_MAX_DEG, Step, Terrain

STEP = Step(1.0, 2.0, -1.0, 1.0, 0.2)  # [m]
SLOPED = Terrain(10.0, 30.0, (STEP,))


def test_level_ground_is_the_plane_z_0() -> None:
    assert FLAT.flat and FLAT.normal == (0.0, 0.0, 1.0)
    assert FLAT.contact_plane(3.0, -2.0, 0.5) == FLAT_PLANE
    assert FLAT.height_m(5.0, 7.0) == 0.0
    np.testing.assert_array_equal(FLAT.ground_frame(), np.eye(3))


@settings(max_examples=50, deadline=None)
@given(
    slope=st.floats(0.0, SLOPE_MAX_DEG),
    azimuth=st.floats(-360.0, 360.0),
    x=st.floats(-20.0, 20.0),
    y=st.floats(-20.0, 20.0),
)
def test_the_base_plane_rises_with_its_slope_and_is_normal_to_its_normal(
    slope: float, azimuth: float, x: float, y: float
) -> None:
    terrain = Terrain(slope, azimuth)
    n = np.array(terrain.normal)
    assert np.linalg.norm(n) == pytest.approx(1.0)
    assert math.degrees(math.atan2(math.hypot(n[0], n[1]), n[2])) == pytest.approx(slope, abs=1e-9)
    # a point of the surface is at distance 0; one 1 m above along the normal at 1 m
    surface = np.array([x, y, terrain.height_m(x, y)])
    assert terrain.signed_distance_m(surface)[0] == pytest.approx(0.0, abs=1e-9)
    assert terrain.signed_distance_m(surface + n)[0] == pytest.approx(1.0)
    frame = terrain.ground_frame()
    np.testing.assert_allclose(frame @ frame.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(frame[:, 2], n, atol=1e-12)


def test_the_ground_rises_towards_the_azimuth() -> None:
    terrain = Terrain(10.0, 90.0)  # rises towards +y
    assert terrain.height_m(0.0, 1.0) == pytest.approx(math.tan(math.radians(10.0)))
    assert terrain.height_m(1.0, 0.0) == pytest.approx(0.0, abs=1e-12)


def test_a_step_raises_the_ground_over_its_footprint() -> None:
    base = SLOPED.base_height_m(1.5, 0.0)
    assert SLOPED.height_m(1.5, 0.0) == pytest.approx(base + 0.2)
    assert SLOPED.height_m(2.5, 0.0) == pytest.approx(SLOPED.base_height_m(2.5, 0.0))
    np.testing.assert_allclose(
        SLOPED.heights_m([[1.5, 0.0], [2.5, 0.0]]),
        [SLOPED.height_m(1.5, 0.0), SLOPED.height_m(2.5, 0.0)],
    )


def test_a_point_touches_the_step_top_or_the_wall_it_came_through() -> None:
    terrain = Terrain(0.0, 0.0, (STEP,))
    # above the top, or just below it: the top (normal up, at the step's height)
    assert terrain.contact_plane(1.5, 0.0, 0.25) == (0.0, 0.0, 1.0, 0.2)
    assert terrain.contact_plane(1.5, 0.0, 0.19) == (0.0, 0.0, 1.0, 0.2)
    # 1 cm inside the wall at x = 1 and 10 cm below the top: that wall, pushing to -x
    assert terrain.contact_plane(1.01, 0.0, 0.1) == (-1.0, 0.0, 0.0, -1.0)
    assert terrain.signed_distance_m([1.01, 0.0, 0.1])[0] == pytest.approx(-0.01)
    # beside the step: the base plane
    assert terrain.contact_plane(0.9, 0.0, 0.1) == (0.0, 0.0, 1.0, 0.0)


def test_the_tether_over_a_step_touches_it() -> None:
    terrain = Terrain(0.0, 0.0, (STEP,))
    assert terrain.segment_clearance_m([0.0, 0.0, 0.1], [3.0, 0.0, 0.1]) < 0.0
    assert terrain.segment_clearance_m([0.0, 0.0, 0.3], [3.0, 0.0, 0.3]) == pytest.approx(0.1)


def test_the_rangefinder_reads_the_terrain_along_its_ray() -> None:
    eye = np.eye(3)
    assert terrain_range_m(FLAT, (0.0, 0.0, 1.0), eye) == downward_range_m(1.0, eye)
    # over the step, on the slope: the step's top is closer
    expected = 1.0 - SLOPED.height_m(1.5, 0.0)
    assert terrain_range_m(SLOPED, (1.5, 0.0, 1.0), eye) == pytest.approx(expected, abs=2e-6)
    # tilted with the slope: the ray meets the plane at 1 m along the normal
    terrain = Terrain(10.0, 0.0)
    frame = terrain.ground_frame()
    origin = np.array(terrain.normal)  # 1 m above the origin along the normal
    assert terrain_range_m(terrain, origin, frame) == pytest.approx(1.0, abs=2e-6)
    up = Rotation.from_euler("x", 180.0, degrees=True).as_matrix()
    assert terrain_range_m(terrain, origin, up) == math.inf


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"slope_deg": 90.0}, "slope_deg"),
        ({"slope_deg": -1.0}, "slope_deg"),
        ({"slope_deg": math.nan}, "slope_deg"),
        ({"slope_azimuth_deg": math.inf}, "slope_azimuth_deg"),
    ],
)
def test_a_bad_terrain_is_refused_naming_the_field(kwargs: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        Terrain(**kwargs)


@pytest.mark.parametrize(
    ("values", "field"),
    [
        ((2.0, 1.0, -1.0, 1.0, 0.2), "x_m"),
        ((1.0, 2.0, 1.0, -1.0, 0.2), "y_m"),
        ((1.0, 2.0, -1.0, 1.0, 0.0), "height_m"),
        ((1.0, 2.0, -1.0, 1.0, math.nan), "height_m"),
    ],
)
def test_a_bad_step_is_refused_naming_the_field(values: tuple, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        Step(*values)


def test_the_parameters_round_trip() -> None:
    again = Terrain.from_parameters(10.0, 30.0, SLOPED.steps_flat())
    assert again == SLOPED
    with pytest.raises(ValueError, match="ground_steps_m"):
        Terrain.from_parameters(0.0, 0.0, (1.0, 2.0, 3.0))
