"""Feasibility projection: a requested principal inertia onto the reachable set.

The principal moments are linear in the squared radii (paper eq. 2)::

    I = A s,   s = (r_x^2, r_y^2, r_z^2),
    A = [[0, 4 m_y, 4 m_z], [M_t, 0, 4 m_z], [M_t, 4 m_y, 0]],  M_t = 2 m_x + 4 m_y + 4 m_z

so the reachable set, radii in the box ``[radii_min_m, radii_max_m]`` (tether length
range and knee range), is the parallelepiped ``A [s_min, s_max]``. It lies inside
the cone of the triangle inequalities (``Ixx + Iyy >= Izz`` and so on), since each
inequality is a non-negative radicand of the paper's eq. 3.

Metric: Euclidean distance in inertia space [kg m^2], the quantity the MPC plans
and weighs. The nearest point is a strictly convex box-constrained least-squares
problem in ``s`` (``A`` is invertible); it is solved exactly by enumerating the
3^3 active sets (each squared radius free, at its lower or at its upper bound)
and keeping the feasible candidate of least distance. No iteration, no tolerance
on convergence, deterministic. Any finite request works, up to the largest float:
squared distances are compared less the common ``|b|^2`` and divided by the
request's magnitude (so they neither overflow nor drown in rounding), and
candidates that overflow are skipped; the 8 vertices are always candidates.
"""

from __future__ import annotations

import functools
import itertools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.model import RobotModel, principal_inertia

AXES = ("r_x", "r_y", "r_z")
# A request within this relative distance of the reachable set counts as reachable
# (it is still projected). The MPC meets its radius bounds to its solver's tolerance,
# so a plan on a bound lands ~1e-8 outside; that is not a saturation worth reporting.
SATURATION_RELATIVE_TOLERANCE = 1e-6


@dataclass(frozen=True)
class ProjectionResult:
    """The reachable inertia nearest to a request, and how far it had to move."""

    inertia_kg_m2: NDArray[np.float64]  # (3,) achieved principal moments [kg m^2]
    radii_m: NDArray[np.float64]  # (3,) (r_x, r_y, r_z) [m] producing them
    saturated: bool  # the request was outside the reachable set
    saturation_kg_m2: NDArray[np.float64]  # (3,) achieved - requested [kg m^2]
    reason: str  # "reachable", or which bounds and inequalities were hit


def inertia_map(model: RobotModel) -> NDArray[np.float64]:
    """The matrix A [kg] with ``principal_inertia(r) = A @ r**2`` (columns from the model).

    Read-only; computed once per model (every allocation projects its setpoint).
    """
    return _inertia_map(model)


@functools.lru_cache(maxsize=16)
def _inertia_map(model: RobotModel) -> NDArray[np.float64]:
    a = np.stack([principal_inertia(model, e) for e in np.eye(3)], axis=1)
    a.flags.writeable = False
    return a


def reachable_inertia_bounds(model: RobotModel) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per-axis (min, max) principal moments over the reachable set [kg m^2].

    ``A`` has non-negative entries, so the extremes are at the radius bounds.
    """
    return (
        principal_inertia(model, model.radii_min_m),
        principal_inertia(model, model.radii_max_m),
    )


def _box_least_squares(
    a: NDArray[np.float64], b: NDArray[np.float64], lo: NDArray[np.float64], hi: NDArray[np.float64]
) -> NDArray[np.float64]:
    """argmin |a s - b| over lo <= s <= hi, invertible 3x3 ``a``: exact active-set enumeration.

    Raises ``ValueError`` if no candidate is finite, which cannot happen for a finite
    ``b`` (the vertices are finite and their scaled distances cannot overflow).
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
        best, best_cost = None, math.inf
        for pattern in itertools.product((0, 1, 2), repeat=3):  # 0 free, 1 at lo, 2 at hi
            s = np.where(np.array(pattern) == 1, lo, hi).astype(float)
            free = [i for i, p in enumerate(pattern) if p == 0]
            if free:
                fixed = [i for i, p in enumerate(pattern) if p != 0]
                rhs = b - a[:, fixed] @ s[fixed]
                if len(free) == 3:
                    s_free = np.linalg.solve(a, rhs)
                else:
                    s_free = np.linalg.lstsq(a[:, free], rhs, rcond=None)[0]
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
    if best is None:
        raise ValueError(f"no finite projection of the requested inertia {b.tolist()}")
    return best


def _describe(model: RobotModel, requested: NDArray[np.float64], radii: NDArray[np.float64]) -> str:
    reasons = []
    if np.any(requested <= 0.0):
        reasons.append("non-positive moment requested")
    with np.errstate(over="ignore", invalid="ignore"):  # only its signs are used
        unconstrained = np.linalg.solve(inertia_map(model), requested)
    if np.any(unconstrained < 0.0):
        names = ", ".join(AXES[i] for i in np.flatnonzero(unconstrained < 0.0))
        reasons.append(f"violates a triangle inequality of the principal moments ({names}^2 < 0)")
    r_min, r_max = model.radii_min_m, model.radii_max_m
    for i, axis in enumerate(AXES):
        what = "tether" if i == 0 else "knee"
        if radii[i] <= r_min[i] * (1.0 + 1e-12):
            reasons.append(f"{axis} at its minimum {r_min[i]:.4f} m ({what} limit)")
        elif radii[i] >= r_max[i] * (1.0 - 1e-12):
            reasons.append(f"{axis} at its maximum {r_max[i]:.4f} m ({what} limit)")
    return "outside the reachable set: " + "; ".join(reasons)


def project_inertia(model: RobotModel, requested_inertia_kg_m2: ArrayLike) -> ProjectionResult:
    """Nearest reachable principal inertia (Euclidean in inertia space) to a request.

    Reachable: radii within ``[model.radii_min_m, model.radii_max_m]``. Never
    returns NaN. Raises ``ValueError`` for a non-finite request or one that is
    not three numbers.
    """
    requested = np.asarray(requested_inertia_kg_m2, dtype=float)
    if requested.shape != (3,):
        raise ValueError(f"requested inertia must be 3 numbers, got shape {requested.shape}")
    if not np.all(np.isfinite(requested)):
        raise ValueError(f"requested inertia must be finite, got {requested.tolist()}")
    a = inertia_map(model)
    s = _box_least_squares(a, requested, model.radii_min_m**2, model.radii_max_m**2)
    radii = np.sqrt(s)
    achieved = principal_inertia(model, radii)
    saturation = achieved - requested
    # |saturation| > tol * max(1, |requested|), both sides divided by k (no overflow)
    k = max(1.0, float(np.max(np.abs(requested))))
    tolerance = SATURATION_RELATIVE_TOLERANCE * max(1.0 / k, float(np.linalg.norm(requested / k)))
    saturated = bool(np.linalg.norm(saturation / k) > tolerance)
    reason = _describe(model, requested, radii) if saturated else "reachable"
    return ProjectionResult(
        inertia_kg_m2=achieved,
        radii_m=radii,
        saturated=saturated,
        saturation_kg_m2=saturation,
        reason=reason,
    )
