"""The gait's sensors' geometry: a rangefinder ray along base -z against the ground z = 0."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from splitter_model.sensors import (
    RANGE_MAX_M,
    RANGE_MIN_M,
    downward_range_m,
    hemi_height_from_range,
)


def test_level_body_reads_its_height() -> None:
    assert downward_range_m(1.7, np.eye(3)) == pytest.approx(1.7)


@pytest.mark.parametrize("tilt_deg", [0.0, 20.0, 45.0, 70.0])
def test_a_tilted_ray_reads_the_slant_distance_and_gives_the_height_back(tilt_deg: float) -> None:
    rot = Rotation.from_euler("x", tilt_deg, degrees=True).as_matrix()
    reading = downward_range_m(1.2, rot)
    assert reading == pytest.approx(1.2 / math.cos(math.radians(tilt_deg)))
    assert hemi_height_from_range(reading, rot) == pytest.approx(1.2)


def test_no_ground_on_the_ray_reads_infinity() -> None:
    upside_down = Rotation.from_euler("x", 180.0, degrees=True).as_matrix()
    sideways = Rotation.from_euler("y", 90.0, degrees=True).as_matrix()
    assert downward_range_m(1.0, upside_down) == math.inf
    assert downward_range_m(1.0, sideways) == math.inf
    assert downward_range_m(RANGE_MAX_M + 1.0, np.eye(3)) == math.inf
    assert downward_range_m(0.5 * RANGE_MIN_M, np.eye(3)) == -math.inf
    assert hemi_height_from_range(math.inf, np.eye(3)) is None
    assert hemi_height_from_range(2.0, upside_down) is None
