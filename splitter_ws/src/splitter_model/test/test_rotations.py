"""The one quaternion rotation: known rotations, scipy's Rotation, orthonormality, the product."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from splitter_model.rotations import (
    quaternion_multiply,
    quaternion_product,
    quaternion_to_matrix,
    quaternion_to_matrix_entries,
)

RNG = np.random.default_rng(29)
QUATERNIONS = RNG.normal(size=(200, 4))  # any norm: the formula divides by |q|^2
HALF = math.sqrt(0.5)


@pytest.mark.parametrize(
    ("q_wxyz", "expected"),
    [
        ((1.0, 0.0, 0.0, 0.0), np.eye(3)),
        ((0.0, 1.0, 0.0, 0.0), np.diag([1.0, -1.0, -1.0])),  # half turn about x
        ((HALF, 0.0, 0.0, HALF), [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
        ((HALF, 0.0, HALF, 0.0), [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]),
        ((0.5, 0.5, 0.5, 0.5), [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
        ((-2.0, 0.0, 0.0, 0.0), np.eye(3)),  # scale and sign do not matter
    ],
)
def test_known_quaternions_rotate_as_expected(q_wxyz, expected) -> None:
    np.testing.assert_allclose(quaternion_to_matrix(q_wxyz), expected, atol=1e-15)


def test_agrees_with_scipy_rotation() -> None:
    for q in QUATERNIONS:
        expected = Rotation.from_quat(q, scalar_first=True).as_matrix()  # normalises
        np.testing.assert_allclose(quaternion_to_matrix(q), expected, atol=1e-14)


def test_matrices_are_orthonormal_rotations() -> None:
    for q in QUATERNIONS:
        r = quaternion_to_matrix(q)
        np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-14)
        assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-14)


def test_scalar_entries_are_the_matrix_row_major() -> None:
    for q in QUATERNIONS[:20]:
        entries = quaternion_to_matrix_entries(*q.tolist())
        assert all(isinstance(e, float) for e in entries)
        assert np.array_equal(np.array(entries).reshape(3, 3), quaternion_to_matrix(q))


def test_symbolic_entries_evaluate_to_the_numbers() -> None:
    casadi = pytest.importorskip("casadi")
    q = casadi.SX.sym("q", 4)
    f = casadi.Function(
        "r", [q], [casadi.vertcat(*quaternion_to_matrix_entries(*casadi.vertsplit(q)))]
    )
    for value in QUATERNIONS[:20]:
        np.testing.assert_allclose(
            np.array(f(value)).reshape(3, 3), quaternion_to_matrix(value), rtol=0.0, atol=1e-15
        )


@pytest.mark.parametrize(
    "q_wxyz", [(0.0, 0.0, 0.0, 0.0), (math.nan, 0.0, 0.0, 1.0), (1e-13, 0, 0, 0)]
)
def test_no_rotation_is_refused(q_wxyz) -> None:
    with pytest.raises(ValueError, match="not a rotation"):
        quaternion_to_matrix(q_wxyz)


def test_product_composes_rotations() -> None:
    for p, q in zip(QUATERNIONS[:100], QUATERNIONS[100:], strict=True):
        pq = quaternion_multiply(p, q)
        np.testing.assert_allclose(
            quaternion_to_matrix(pq), quaternion_to_matrix(p) @ quaternion_to_matrix(q), atol=1e-13
        )
        expected = (
            Rotation.from_quat(p, scalar_first=True) * Rotation.from_quat(q, scalar_first=True)
        ).as_quat(scalar_first=True, canonical=False)
        np.testing.assert_allclose(pq / np.linalg.norm(pq), expected, atol=1e-14)


def test_symbolic_product_is_the_numeric_product() -> None:
    casadi = pytest.importorskip("casadi")
    p, q = casadi.SX.sym("p", 4), casadi.SX.sym("q", 4)
    f = casadi.Function("pq", [p, q], [casadi.vertcat(*quaternion_product(p, q))])
    for a, b in zip(QUATERNIONS[:20], QUATERNIONS[20:40], strict=True):
        np.testing.assert_allclose(
            np.array(f(a, b)).ravel(), quaternion_multiply(a, b), rtol=0.0, atol=1e-15
        )
