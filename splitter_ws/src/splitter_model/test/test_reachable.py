"""The one reachable set of principal inertia: its map, its box, its bounds, its projection."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from splitter_model.model import RobotModel, principal_inertia, radii_from_inertia
from splitter_model.reachable import inertia_map, radius_squared_matrix, reachable_set

MODEL = RobotModel()
REACHABLE = reachable_set(MODEL)
S_MIN, S_MAX = REACHABLE.radius_squared_min_m2, REACHABLE.radius_squared_max_m2
VERTICES = np.array(
    [np.where(np.array(p), S_MAX, S_MIN) for p in itertools.product((0, 1), repeat=3)]
)
squared_radii = st.tuples(
    *(st.floats(float(lo), float(hi)) for lo, hi in zip(S_MIN, S_MAX, strict=True))
)
moments = st.tuples(*[st.floats(-50.0, 250.0)] * 3)


def test_map_and_its_closed_form_inverse_are_the_papers_equations() -> None:
    # eq. (2) at the paper's masses: M_t = 18 kg, 4 m_y = 4 m_z = 6 kg
    np.testing.assert_array_equal(inertia_map(MODEL), [[0, 6, 6], [18, 0, 6], [18, 6, 0]])
    np.testing.assert_allclose(
        inertia_map(MODEL) @ radius_squared_matrix(MODEL), np.eye(3), atol=1e-15
    )
    r = np.array([2.1, 0.3, 0.2])
    np.testing.assert_allclose(REACHABLE.inertia(r**2), principal_inertia(MODEL, r), rtol=1e-15)
    np.testing.assert_allclose(
        np.sqrt(REACHABLE.radii_squared(principal_inertia(MODEL, r))),
        radii_from_inertia(MODEL, principal_inertia(MODEL, r)),
        rtol=1e-14,
    )


def test_box_and_bounds_come_from_the_tether_and_knee_limits() -> None:
    np.testing.assert_array_equal(REACHABLE.radius_min_m, MODEL.radii_min_m)
    np.testing.assert_array_equal(REACHABLE.radius_max_m, MODEL.radii_max_m)
    assert REACHABLE.radius_min_m[0] == MODEL.tether_length_min_m / 2.0
    assert REACHABLE.radius_max_m[1] == MODEL.limb_reach_m(MODEL.knee_min_rad)
    inertia = REACHABLE.inertia(VERTICES)
    np.testing.assert_allclose(REACHABLE.inertia_min_kg_m2, inertia.min(axis=0), rtol=1e-15)
    np.testing.assert_allclose(REACHABLE.inertia_max_kg_m2, inertia.max(axis=0), rtol=1e-15)
    assert reachable_set(MODEL) is REACHABLE  # one per model
    with pytest.raises(ValueError):
        REACHABLE.radius_min_m[0] = 0.0  # shared: read-only


@settings(max_examples=300, deadline=None)
@given(squared_radii)
def test_reachable_moments_are_contained_and_their_own_projection(s: tuple) -> None:
    inertia = REACHABLE.inertia(s)
    assert REACHABLE.contains(inertia)
    np.testing.assert_allclose(REACHABLE.project(inertia), s, rtol=1e-9, atol=1e-12)


@settings(max_examples=300, deadline=None)
@given(moments, squared_radii)
def test_projection_is_the_nearest_reachable_inertia(request: tuple, other: tuple) -> None:
    """Euclidean in principal inertia: no reachable point (vertex or any other) is nearer."""
    b = np.array(request)
    s = REACHABLE.project(b)
    assert np.all(s >= S_MIN) and np.all(s <= S_MAX)
    distance = np.linalg.norm(REACHABLE.inertia(s) - b)
    nearest_vertex = np.min(np.linalg.norm(REACHABLE.inertia(VERTICES) - b, axis=1))
    assert distance <= nearest_vertex + 1e-9 * (1.0 + nearest_vertex)
    assert distance <= np.linalg.norm(REACHABLE.inertia(other) - b) + 1e-9 * (1.0 + distance)


def test_projection_moves_every_radius_that_brings_the_inertia_closer() -> None:
    """A too-long tether: clipping r_x alone is not the nearest inertia, stretching limbs helps."""
    s = REACHABLE.project(principal_inertia(MODEL, [3.5, 0.2, 0.2]))
    np.testing.assert_allclose(np.sqrt(s), [3.0, MODEL.limb_radius_max_m, MODEL.limb_radius_max_m])
    with pytest.raises(ValueError):
        REACHABLE.project([1.0, np.nan, 1.0])
    with pytest.raises(ValueError):
        REACHABLE.project([1.0, 1.0])


@settings(max_examples=200, deadline=None)
@given(st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda e: np.linalg.norm(e) > 1e-3))
def test_axis_inertia_range_is_spanned_by_the_vertices(axis: tuple) -> None:
    e = np.array(axis) / np.linalg.norm(axis)
    low, high = REACHABLE.axis_inertia_range(e)
    about_e = REACHABLE.inertia(VERTICES) @ (e * e)
    assert low == pytest.approx(about_e.min(), rel=1e-12)
    assert high == pytest.approx(about_e.max(), rel=1e-12)


def _plain_projection(b: np.ndarray) -> np.ndarray:
    """The enumeration written plainly: every active set solved with lstsq, in order."""
    a, lo, hi = REACHABLE.inertia_map, S_MIN, S_MAX
    slack = 1e-12 * np.maximum(1.0, np.abs(hi))
    scale = max(1.0, float(np.max(np.abs(b))))
    interior = np.linalg.solve(a, b)
    if np.all(interior >= lo - slack) and np.all(interior <= hi + slack):
        return np.clip(interior, lo, hi)
    best, best_cost = None, np.inf
    for active in itertools.product((0, 1, 2), repeat=3):
        pattern = np.array(active)
        if not pattern.any():
            continue  # all free: the interior, infeasible here
        s = np.where(pattern == 1, lo, hi).astype(float)
        free = pattern == 0
        if free.any():
            rhs = b - a[:, ~free] @ s[~free]
            s_free = np.linalg.lstsq(a[:, free], rhs, rcond=None)[0]
            if np.any(s_free < lo[free] - slack[free]) or np.any(s_free > hi[free] + slack[free]):
                continue
            s[free] = np.clip(s_free, lo[free], hi[free])
        achieved = a @ s
        cost = float(achieved @ achieved / scale - 2.0 * (b / scale) @ achieved)
        if cost < best_cost:
            best, best_cost = s, cost
    return best


def test_the_projection_is_the_plain_enumeration_bit_for_bit() -> None:
    """All active sets at once (the allocator's every tick) gives the same bits,
    also where two faces tie (the first request: a lunar MPC plan's, I_yy = I_zz)."""
    tied = np.array([1.016951632033563, 162.07187522935556, 162.94507872552538])
    np.testing.assert_array_equal(REACHABLE.project(tied), _plain_projection(tied))
    rng = np.random.default_rng(11)
    for k in range(3000):
        b = rng.normal(0.0, 1.0, 3) * 10.0 ** rng.uniform(-2.0, 4.0 if k % 7 else 12.0)
        np.testing.assert_array_equal(REACHABLE.project(b), _plain_projection(b), err_msg=str(b))
