"""Feasibility projection of any finite request, up to the largest float (no assert, no NaN)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from splitter_ik.core.projection import project_inertia, reachable_inertia_bounds
from splitter_model.model import RobotModel
from splitter_model.reachable import inertia_map

# An overflow inside the projection would be a number it does not handle.
pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")

MODEL = RobotModel()
A = inertia_map(MODEL)
S_MIN, S_MAX = MODEL.radii_min_m**2, MODEL.radii_max_m**2
VERTICES = [np.where(np.array(p), S_MAX, S_MIN) for p in itertools.product((0, 1), repeat=3)]
FINITE = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False),
    st.sampled_from([1e300, -1e300, 1e-300, 1.7976931348623157e308, -1.7976931348623157e308]),
)


def _scaled_cost(s: np.ndarray, b: np.ndarray) -> float:
    """(|A s - b|^2 - |b|^2) / max(1, |b|_inf): ordered as the distance, never overflows."""
    scale = max(1.0, float(np.max(np.abs(b))))
    achieved = A @ s
    return float(achieved @ achieved / scale - 2.0 * (b / scale) @ achieved)


@settings(max_examples=300, deadline=None)
@given(st.tuples(FINITE, FINITE, FINITE))
def test_any_finite_request_has_a_finite_nearest_point(request: tuple[float, ...]) -> None:
    b = np.array(request)
    result = project_inertia(MODEL, b)
    assert np.all(np.isfinite(result.radii_m)) and np.all(np.isfinite(result.inertia_kg_m2))
    assert np.all(result.radii_m >= MODEL.radii_min_m)
    assert np.all(result.radii_m <= MODEL.radii_max_m)
    assert isinstance(result.saturated, bool) and result.reason
    # no vertex of the reachable set is nearer (within rounding of the scaled costs)
    cost = _scaled_cost(result.radii_m**2, b)
    slack = 1e-9 * max(1.0, abs(cost))
    assert all(cost <= _scaled_cost(v, b) + slack for v in VERTICES)


@pytest.mark.parametrize(
    ("request_kg_m2", "corner"),
    [
        ([1e300] * 3, "max"),
        ([1.7976931348623157e308] * 3, "max"),
        ([-1e300] * 3, "min"),
        ([1e-300] * 3, "min"),
    ],
)
def test_extreme_requests_land_on_the_expected_corner(request_kg_m2, corner: str) -> None:
    result = project_inertia(MODEL, request_kg_m2)
    low, high = reachable_inertia_bounds(MODEL)
    np.testing.assert_allclose(result.inertia_kg_m2, high if corner == "max" else low)
    assert result.saturated
    assert math.isfinite(float(np.max(np.abs(result.saturation_kg_m2))))
