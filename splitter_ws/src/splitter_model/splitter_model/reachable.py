"""The reachable set of principal inertia: the one description the MPC and the allocator share.

The principal moments are linear in the squared radii (paper eq. 2)::

    I = A s,   s = (r_x^2, r_y^2, r_z^2),
    A = [[0, 4 m_y, 4 m_z], [M_t, 0, 4 m_z], [M_t, 4 m_y, 0]],  M_t = 2 m_x + 4 m_y + 4 m_z

and ``s = R I`` with ``R = A^-1``, whose rows are the radicands of the paper's
closed form (eq. 3). ``r_x`` is half the tether length, ``r_y`` and ``r_z`` the limb
reach over the knee range (:attr:`RobotModel.radii_min_m`, ``radii_max_m``), so the
radii form a box and the squared radii the box ``[s_min, s_max]``. The reachable
inertia is the parallelepiped ``A [s_min, s_max]``: an exact, linear description
(the MPC's radius bounds are simple bounds on ``s``). It lies inside the cone of
the triangle inequalities (``Ixx + Iyy >= Izz`` and so on), since each inequality
is a non-negative radicand of eq. 3.

Closest reachable inertia: Euclidean distance in principal inertia [kg m^2], the
quantity the MPC plans and weighs and the allocator is asked for. The nearest
point is a strictly convex box-constrained least-squares problem in ``s`` (``A`` is
invertible); it is solved exactly by enumerating the 3^3 active sets (each
squared radius free, at its lower or at its upper bound) and keeping the feasible
candidate of least distance. No iteration, no tolerance on convergence,
deterministic. Any finite request works, up to the largest float: squared
distances are compared less the common ``|b|^2`` and divided by the request's
magnitude (so they neither overflow nor drown in rounding), and candidates that
overflow are skipped; the 8 vertices are always candidates.

ROS-free, numpy-only.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.model import RobotModel, principal_inertia


def _read_only(array: ArrayLike) -> NDArray[np.float64]:
    out = np.array(array, dtype=float)
    out.flags.writeable = False
    return out


@dataclass(frozen=True)
class ReachableSet:
    """Principal moments the tether and limbs can produce: ``I = A s``, ``s`` in a box.

    Per-axis arrays are ordered (x, y, z): radii (r_x, r_y, r_z), moments
    (Ixx, Iyy, Izz). Arrays are read-only (one instance is shared per model).
    """

    inertia_map: NDArray[np.float64]  # (3, 3) [kg] A, I = A s
    radius_squared_matrix: NDArray[np.float64]  # (3, 3) [1/kg] R = A^-1, s = R I (eq. 3)
    radius_min_m: NDArray[np.float64]  # (3,) [m] r_min: shortest tether / 2, folded knee
    radius_max_m: NDArray[np.float64]  # (3,) [m] r_max: longest tether / 2, stretched knee
    inertia_min_kg_m2: NDArray[np.float64]  # (3,) [kg m^2] per-axis smallest, A s_min
    inertia_max_kg_m2: NDArray[np.float64]  # (3,) [kg m^2] per-axis largest, A s_max

    @property
    def radius_squared_min_m2(self) -> NDArray[np.float64]:
        """Lower corner ``s_min`` of the box of squared radii [m^2]."""
        return self.radius_min_m**2

    @property
    def radius_squared_max_m2(self) -> NDArray[np.float64]:
        """Upper corner ``s_max`` of the box of squared radii [m^2]."""
        return self.radius_max_m**2

    def radii_squared(self, inertia_kg_m2: ArrayLike) -> NDArray[np.float64]:
        """``s = R I`` [m^2] of principal moments (..., 3) (negative if no radii give them)."""
        return np.asarray(inertia_kg_m2, dtype=float) @ self.radius_squared_matrix.T

    def inertia(self, radii_squared_m2: ArrayLike) -> NDArray[np.float64]:
        """``I = A s`` [kg m^2] of squared radii (..., 3)."""
        return np.asarray(radii_squared_m2, dtype=float) @ self.inertia_map.T

    def contains(self, inertia_kg_m2: ArrayLike, tol_m2: float = 1e-9) -> bool:
        """True when the moments come from radii inside the bounds (``tol_m2`` on ``s``)."""
        s = self.radii_squared(inertia_kg_m2)
        return bool(
            np.all(s >= self.radius_squared_min_m2 - tol_m2)
            and np.all(s <= self.radius_squared_max_m2 + tol_m2)
        )

    def project(self, inertia_kg_m2: ArrayLike) -> NDArray[np.float64]:
        """Squared radii ``s`` [m^2] of the reachable moments nearest (Euclidean) to a request.

        Raises ``ValueError`` for a request that is not three finite numbers.
        """
        requested = np.asarray(inertia_kg_m2, dtype=float)
        if requested.shape != (3,):
            raise ValueError(f"requested inertia must be 3 numbers, got shape {requested.shape}")
        if not np.all(np.isfinite(requested)):
            raise ValueError(f"requested inertia must be finite, got {requested.tolist()}")
        return _box_least_squares(
            self.inertia_map, requested, self.radius_squared_min_m2, self.radius_squared_max_m2
        )

    def axis_inertia_range(self, axis: ArrayLike) -> tuple[float, float]:
        """Smallest and largest moment ``e' I e`` [kg m^2] about the body axis ``e`` within reach.

        ``e' I e = (e^2)' A s`` is linear in ``s`` over a box, so each extreme sits
        at a corner chosen by the signs of ``(e^2)' A``.
        """
        e_sq = np.asarray(axis, dtype=float).reshape(3) ** 2
        coefficients = e_sq @ self.inertia_map  # [kg] per m^2
        low, high = self.radius_squared_min_m2, self.radius_squared_max_m2
        smallest = float(coefficients @ np.where(coefficients >= 0.0, low, high))
        largest = float(coefficients @ np.where(coefficients >= 0.0, high, low))
        return smallest, largest


def inertia_map(model: RobotModel) -> NDArray[np.float64]:
    """A [kg] with ``principal_inertia(r) = A @ r**2``: columns of eq. (2) at unit radii."""
    return np.stack([principal_inertia(model, e) for e in np.eye(3)], axis=1)


def radius_squared_matrix(model: RobotModel) -> NDArray[np.float64]:
    """R [1/kg] with ``(r_x^2, r_y^2, r_z^2) = R (Ixx, Iyy, Izz)``: the radicands of eq. (3).

    The inverse of :func:`inertia_map` in closed form; works for any masses.
    """
    mx, my, mz = model.body_mass_kg, model.limb_mass_y_kg, model.limb_mass_z_kg
    hemi = mx + 2.0 * my + 2.0 * mz
    return np.array(
        [
            [-1.0, 1.0, 1.0],
            [1.0, -1.0, 1.0],
            [1.0, 1.0, -1.0],
        ]
    ) / np.array([[4.0 * hemi], [8.0 * my], [8.0 * mz]])


@functools.lru_cache(maxsize=16)
def reachable_set(model: RobotModel) -> ReachableSet:
    """The reachable set of ``model`` (computed once per model, shared, read-only)."""
    r_min = np.asarray(model.radii_min_m, dtype=float)
    r_max = np.asarray(model.radii_max_m, dtype=float)
    return ReachableSet(
        inertia_map=_read_only(inertia_map(model)),
        radius_squared_matrix=_read_only(radius_squared_matrix(model)),
        radius_min_m=_read_only(r_min),
        radius_max_m=_read_only(r_max),
        inertia_min_kg_m2=_read_only(principal_inertia(model, r_min)),
        inertia_max_kg_m2=_read_only(principal_inertia(model, r_max)),
    )


# Every active set but "all free" (the interior, solved first): 0 free, 1 at lo, 2 at hi.
_ACTIVE_SETS = np.array(list(itertools.product((0, 1, 2), repeat=3))[1:])
_FREE = _ACTIVE_SETS == 0
_AT_LOW = _ACTIVE_SETS == 1
# [-] relative: how near feasible and how near the least cost an active set of the
# all-at-once pass must be to be solved the plain way (the two differ by ~1e-8 at most)
_CONTENDER_MARGIN = 1e-6


@functools.lru_cache(maxsize=16)
def _free_solvers(a_bytes: bytes) -> NDArray[np.float64]:
    """(26, 3, 3): per active set, the least-squares map rhs -> free squared radii.

    Row ``i`` of a set's matrix is zero unless ``s_i`` is free; the free rows are the
    pseudo-inverse of ``a``'s free columns (what ``lstsq`` would solve, built once).
    """
    a = np.frombuffer(a_bytes, dtype=float).reshape(3, 3)
    solvers = np.zeros((len(_ACTIVE_SETS), 3, 3))
    for k, free in enumerate(_FREE):
        solvers[k][free] = np.linalg.pinv(a[:, free])
    solvers.setflags(write=False)
    return solvers


def _box_least_squares(
    a: NDArray[np.float64], b: NDArray[np.float64], lo: NDArray[np.float64], hi: NDArray[np.float64]
) -> NDArray[np.float64]:
    """argmin |a s - b| over lo <= s <= hi, invertible 3x3 ``a``: exact active-set enumeration.

    The answer is that of the plain enumeration (each active set's free radii solved
    with ``lstsq``, checked, costed; the first of least cost wins), bit for bit; but
    all 26 bounded active sets are first solved at once (pseudo-inverses built
    once), and only the contenders (near feasible, cost near the least) are then
    solved the plain way: the allocator projects every tick. Contenders are kept
    with a margin (:data:`_CONTENDER_MARGIN`) far above the two ways' differences
    (~2e-9 m^2 where two faces tie). Raises ``ValueError`` if no candidate is
    finite, which cannot happen for a finite ``b`` (the vertices are finite and
    their scaled distances cannot overflow).
    """
    slack = 1e-12 * np.maximum(1.0, np.abs(hi))
    scale = max(1.0, float(np.max(np.abs(b))))
    b_scaled = b / scale
    # A huge b may overflow the free solves: such candidates are non-finite and skipped.
    with np.errstate(over="ignore", invalid="ignore"):
        interior = np.linalg.solve(a, b)
        if (
            np.all(np.isfinite(interior))
            and np.all(interior >= lo - slack)
            and np.all(interior <= hi + slack)
        ):
            return np.clip(interior, lo, hi)  # the unconstrained minimum is feasible
        bound = np.where(_AT_LOW, lo, hi)  # (26, 3) the bounded entries' values
        rhs = b - np.where(_FREE, 0.0, bound) @ a.T
        s_free = np.einsum("kij,kj->ki", _free_solvers(np.ascontiguousarray(a).tobytes()), rhs)
        margin = _CONTENDER_MARGIN * np.maximum(1.0, np.abs(hi))
        near_feasible = np.all(
            ~_FREE | (np.isfinite(s_free) & (s_free >= lo - margin) & (s_free <= hi + margin)),
            axis=1,
        )
        achieved = np.where(_FREE, np.clip(s_free, lo, hi), bound) @ a.T
        cost = np.einsum("ki,ki->k", achieved, achieved) / scale - 2.0 * achieved @ b_scaled
        cost = np.where(near_feasible & np.isfinite(cost), cost, np.inf)
        least = float(np.min(cost))
        if math.isfinite(least):
            contenders = np.flatnonzero(cost <= least + _CONTENDER_MARGIN * max(1.0, abs(least)))
        else:
            contenders = np.arange(len(_ACTIVE_SETS))
        best = _plain_enumeration(a, b, lo, hi, contenders)
        if best is None and len(contenders) < len(_ACTIVE_SETS):
            best = _plain_enumeration(a, b, lo, hi, range(len(_ACTIVE_SETS)))
    if best is None:
        raise ValueError(f"no finite projection of the requested inertia {b.tolist()}")
    return best


def _plain_enumeration(
    a: NDArray[np.float64],
    b: NDArray[np.float64],
    lo: NDArray[np.float64],
    hi: NDArray[np.float64],
    active_sets: Iterable[int],
) -> NDArray[np.float64] | None:
    """The first feasible of least cost among ``active_sets`` (indices), each solved alone."""
    slack = 1e-12 * np.maximum(1.0, np.abs(hi))
    scale = max(1.0, float(np.max(np.abs(b))))
    b_scaled = b / scale
    best, best_cost = None, math.inf
    for k in active_sets:
        free = _FREE[k]
        s = np.where(_AT_LOW[k], lo, hi).astype(float)
        if free.any():
            fixed = ~free
            s_free = np.linalg.lstsq(a[:, free], b - a[:, fixed] @ s[fixed], rcond=None)[0]
            if (
                not np.all(np.isfinite(s_free))
                or np.any(s_free < lo[free] - slack[free])
                or np.any(s_free > hi[free] + slack[free])
            ):
                continue
            s[free] = np.clip(s_free, lo[free], hi[free])
        # (|a s - b|^2 - |b|^2) / scale: same order as the distance, |a s| is bounded
        achieved = a @ s
        cost = float(achieved @ achieved / scale - 2.0 * b_scaled @ achieved)
        if math.isfinite(cost) and (best is None or cost < best_cost):
            best, best_cost = s, cost
    return best
