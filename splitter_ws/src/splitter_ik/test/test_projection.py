"""Feasibility projection: exact on the reachable set, nearest point outside it, never NaN."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import lsq_linear, minimize

from splitter_ik.core.projection import project_inertia, reachable_inertia_bounds
from splitter_model.model import RobotModel, principal_inertia, radii_from_inertia
from splitter_model.reachable import inertia_map

MODEL = RobotModel()
R_MIN, R_MAX = MODEL.radii_min_m, MODEL.radii_max_m

reachable_radii = st.tuples(
    st.floats(float(R_MIN[0]), float(R_MAX[0])),
    st.floats(float(R_MIN[1]), float(R_MAX[1])),
    st.floats(float(R_MIN[2]), float(R_MAX[2])),
)


def _check_round_trip(r: np.ndarray) -> None:
    inertia = principal_inertia(MODEL, r)
    result = project_inertia(MODEL, inertia)
    assert not result.saturated, result.reason
    assert result.reason == "reachable"
    np.testing.assert_allclose(result.radii_m, r, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(radii_from_inertia(MODEL, inertia), r, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(result.inertia_kg_m2, inertia, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(result.saturation_kg_m2, 0.0, atol=1e-9)


def test_radii_inertia_radii_round_trip_over_5000_configurations() -> None:
    rng = np.random.default_rng(11)
    samples = rng.uniform(R_MIN, R_MAX, size=(5000, 3))
    samples[:8] = [[R_MIN[0] if i & 1 else R_MAX[0], R_MIN[1] if i & 2 else R_MAX[1],
                    R_MIN[2] if i & 4 else R_MAX[2]] for i in range(8)]  # fmt: skip
    for r in samples:
        _check_round_trip(r)


@settings(max_examples=300, deadline=None)
@given(reachable_radii)
def test_radii_inertia_radii_round_trip_property(radii: tuple[float, float, float]) -> None:
    _check_round_trip(np.array(radii))


def _distance(point: np.ndarray, request: np.ndarray) -> float:
    return float(np.linalg.norm(point - request))


# A fixed cloud of reachable inertias for brute-force nearest-point checks.
_RNG = np.random.default_rng(7)
_CLOUD = principal_inertia(MODEL, _RNG.uniform(R_MIN, R_MAX, size=(100_000, 3)))


@settings(max_examples=200, deadline=None)
@given(st.tuples(*[st.floats(-400.0, 400.0)] * 3))
def test_projection_is_reachable_finite_and_no_farther_than_any_reachable_point(
    request_tuple: tuple[float, float, float],
) -> None:
    request = np.array(request_tuple)
    result = project_inertia(MODEL, request)
    assert np.all(np.isfinite(result.inertia_kg_m2)) and np.all(np.isfinite(result.radii_m))
    assert np.all(result.radii_m >= R_MIN - 1e-12) and np.all(result.radii_m <= R_MAX + 1e-12)
    np.testing.assert_allclose(result.inertia_kg_m2, principal_inertia(MODEL, result.radii_m))
    np.testing.assert_allclose(result.saturation_kg_m2, result.inertia_kg_m2 - request)
    best_sampled = float(np.min(np.linalg.norm(_CLOUD - request, axis=1)))
    assert _distance(result.inertia_kg_m2, request) <= best_sampled + 1e-9
    if result.saturated:
        assert result.reason.startswith("outside the reachable set")
        assert _distance(result.inertia_kg_m2, request) > 0.0


@pytest.mark.parametrize(
    "request_kg_m2",
    [
        [10.0, 10.0, 10.0],  # limbs cannot make Ixx that large with so little Iyy
        [-1.0, 5.0, 5.0],  # negative moment
        [0.1, 300.0, 100.0],  # triangle inequality Ixx + Izz >= Iyy violated
        [1e6, 1e6, 1e6],  # far beyond every bound
        [0.0, 0.0, 0.0],
        [3.0, 20.0, 150.0],
    ],
)
def test_unreachable_request_matches_independent_optimisers(request_kg_m2: list[float]) -> None:
    request = np.array(request_kg_m2)
    result = project_inertia(MODEL, request)
    assert result.saturated
    # scipy's bounded linear least squares in the squared radii
    lsq = lsq_linear(inertia_map(MODEL), request, bounds=(R_MIN**2, R_MAX**2), tol=1e-14)
    via_lsq = principal_inertia(MODEL, np.sqrt(lsq.x))
    # and a multi-start bounded minimisation directly over the radii
    best = np.inf
    for start in np.random.default_rng(3).uniform(R_MIN, R_MAX, size=(12, 3)):
        opt = minimize(
            lambda r: float(np.sum((principal_inertia(MODEL, r) - request) ** 2)),
            start,
            method="L-BFGS-B",
            bounds=list(zip(R_MIN, R_MAX, strict=True)),
            options={"ftol": 1e-15, "gtol": 1e-12},
        )
        best = min(best, float(np.sqrt(opt.fun)))
    ours = _distance(result.inertia_kg_m2, request)
    assert ours <= _distance(via_lsq, request) + 1e-6
    assert ours <= best + 1e-6
    np.testing.assert_allclose(result.inertia_kg_m2, via_lsq, atol=1e-4)


def test_reason_names_the_bound_hit() -> None:
    result = project_inertia(MODEL, [0.48, 1e4, 1e4])
    assert "r_x at its maximum" in result.reason and "tether" in result.reason
    result = project_inertia(MODEL, [0.1, 300.0, 100.0])
    assert "triangle inequality" in result.reason


def test_reachable_bounds_are_the_corner_inertias() -> None:
    lo, hi = reachable_inertia_bounds(MODEL)
    assert not project_inertia(MODEL, lo).saturated
    assert not project_inertia(MODEL, hi).saturated
    assert project_inertia(MODEL, hi * 1.001).saturated


@pytest.mark.parametrize(
    "bad", [[np.nan, 1.0, 1.0], [1.0, np.inf, 1.0], [1.0, 1.0, -np.inf], [1.0, 2.0], "abc"]
)
def test_non_finite_or_malformed_request_raises(bad: object) -> None:
    with pytest.raises(ValueError):
        project_inertia(MODEL, bad)  # type: ignore[arg-type]
