"""Feasibility projection: a requested principal inertia onto the reachable set.

The reachable set and its projection (Euclidean in principal inertia [kg m^2]) are
:mod:`splitter_model.reachable`, shared with the MPC; this module reports for the
allocator what a projection achieved and, when the request was outside, why.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.model import RobotModel, principal_inertia
from splitter_model.reachable import reachable_set

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


def reachable_inertia_bounds(model: RobotModel) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per-axis (min, max) principal moments over the reachable set [kg m^2] (read-only)."""
    reachable = reachable_set(model)
    return reachable.inertia_min_kg_m2, reachable.inertia_max_kg_m2


def _describe(model: RobotModel, requested: NDArray[np.float64], radii: NDArray[np.float64]) -> str:
    reachable = reachable_set(model)
    reasons = []
    if np.any(requested <= 0.0):
        reasons.append("non-positive moment requested")
    with np.errstate(over="ignore", invalid="ignore"):  # only its signs are used
        unconstrained = np.linalg.solve(reachable.inertia_map, requested)
    if np.any(unconstrained < 0.0):
        names = ", ".join(AXES[i] for i in np.flatnonzero(unconstrained < 0.0))
        reasons.append(f"violates a triangle inequality of the principal moments ({names}^2 < 0)")
    r_min, r_max = reachable.radius_min_m, reachable.radius_max_m
    for i, axis in enumerate(AXES):
        what = "tether" if i == 0 else "knee"
        if radii[i] <= r_min[i] * (1.0 + 1e-12):
            reasons.append(f"{axis} at its minimum {r_min[i]:.4f} m ({what} limit)")
        elif radii[i] >= r_max[i] * (1.0 - 1e-12):
            reasons.append(f"{axis} at its maximum {r_max[i]:.4f} m ({what} limit)")
    return "outside the reachable set: " + "; ".join(reasons)


def project_inertia(model: RobotModel, requested_inertia_kg_m2: ArrayLike) -> ProjectionResult:
    """Nearest reachable principal inertia (Euclidean in inertia space) to a request.

    Reachable: radii within ``[model.radii_min_m, model.radii_max_m]``
    (:meth:`splitter_model.reachable.ReachableSet.project`). Never
    returns NaN. Raises ``ValueError`` for a non-finite request or one that is
    not three numbers.
    """
    requested = np.asarray(requested_inertia_kg_m2, dtype=float)
    radii = np.sqrt(reachable_set(model).project(requested))  # validates the request
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
