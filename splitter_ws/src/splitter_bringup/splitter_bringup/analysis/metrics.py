"""Flight metrics of a run, beside the paper's numbers (section VII.A, Tables I and II).

Pure functions of a :class:`RunSeries`, whichever way it was made (library loop
or a bag of the node graph). Definitions (stated, since the paper does not):

* final window: the last ``FINAL_WINDOW_S`` = 0.5 s of the run. ``residual_wx``,
  ``residual_wz`` are the mean |w_x|, |w_z| over it; ``wy_final`` the mean w_y.
* ``time_constant_s``: first time w_y has covered 63.2 % of its change from t = 0
  to ``wy_final`` (0 for a change under ``NO_SPIN_RAD_S``: round-off is no step).
* ``settling_time_s``: last time |w_y - wy_final| exceeds ``SETTLING_BAND`` = 2 % of
  that change; after it w_y stays in the band.
* ``max_g``: largest specific force on a Hemi-SPLITTER body [G] (the simulator's
  ``hemi_acceleration_g``). For a steady spin about y it is ``w_y^2 r_x / g``: the
  paper's 0.47 G is 1.28^2 x 2.8 / 9.81.
* energy and angular momentum at t = 0 and at the end; ``spin_alignment_final``
  = |w_y| / |w| at the end.
* ``wy_from_momentum``: ``|H| / Iyy`` at the end. With the angular momentum
  conserved in flight and the final spin about y, ``w_y = |H| / Iyy`` exactly:
  the final spin rate is set by the final inertia, not by the reference.
* ``w_tracking_rms_rad_s``: RMS over the whole run of ``|w - w_ref|`` (time
  weighted), how well the angular velocity reference is tracked;
  ``inertia_range_kg_m2``: the largest range (max - min) of Ixx, Iyy, Izz, how
  much morphing a run used. The paper's findings on orientation tracking compare
  these two between variants (:func:`evaluate_findings`).

Attitude error: the angle between the attitude and the reference the MPC was
given, q and -q counted as one attitude. The gait machine makes that reference
on its first tick (t = 0, the first sample) from the measured state;
:func:`attitude_reference_series` rebuilds it from the first sample (q0, w0 and
the principal inertia I0) with the same function
(``splitter_mpc.core.gait.attitude_reference_at_stamp``) and propagates it as the
MPC does: ``q_ref(t) = q_ref(0) (x) exp(w_ref t / 2)`` (body rate), held in mode
``initial``. In mode ``momentum_aligned`` ``q_ref(0)`` has the body axis of w_ref
along the world angular momentum (reachable in torque-free flight).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_bringup.analysis.series import RunSeries
from splitter_bringup.scenario.definition import PaperFinding
from splitter_model.model import STANDARD_GRAVITY
from splitter_mpc.core.gait import attitude_reference_at_stamp, propagate_attitude

FINAL_WINDOW_S = 0.5  # [s]
SETTLING_BAND = 0.02  # [-] of the w_y change
TIME_CONSTANT_FRACTION = 1.0 - math.exp(-1.0)  # 63.2 %
# [rad/s] below it a rate is round-off, not a spin (a symmetric jump's 1e-7 rad/s): a
# w_y change that small is no step (time constant and settling 0) and a final |w| that
# small has no axis (alignment 0), whichever backend computed the flight
NO_SPIN_RAD_S = 1e-3


@dataclass(frozen=True)
class Metric:
    """One number of a run, with its unit, definition and the paper's value."""

    value: float
    unit: str
    definition: str
    paper: float | str | None = None

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def _final_mask(series: RunSeries) -> NDArray[np.bool_]:
    t = series.t_s
    return t >= t[-1] - FINAL_WINDOW_S


def _rotational_energy(series: RunSeries) -> NDArray[np.float64]:
    if "rotational_energy_j" in series.extras:
        return np.asarray(series.extras["rotational_energy_j"], dtype=float)
    w = series.angular_velocity_rad_s
    return 0.5 * np.sum(series.principal_inertia_kg_m2 * w * w, axis=1)


def _momentum_norm(series: RunSeries) -> NDArray[np.float64]:
    if "angular_momentum_world" in series.extras:
        return np.linalg.norm(series.extras["angular_momentum_world"], axis=1)
    return np.linalg.norm(series.principal_inertia_kg_m2 * series.angular_velocity_rad_s, axis=1)


def _hemi_g(series: RunSeries) -> NDArray[np.float64]:
    if "hemi_peak_acceleration_g" in series.extras:  # both backends record the running peak
        return np.asarray(series.extras["hemi_peak_acceleration_g"], dtype=float)
    if "hemi_acceleration_g" in series.extras:
        return np.max(np.asarray(series.extras["hemi_acceleration_g"], dtype=float), axis=1)
    # Centripetal acceleration of a hemi body at (r_x, 0, 0) (rigid-body estimate).
    w = series.angular_velocity_rad_s
    p = np.zeros_like(w)
    p[:, 0] = series.radii_m[:, 0]
    return np.linalg.norm(np.cross(w, np.cross(w, p)), axis=1) / STANDARD_GRAVITY


def step_response(t_s: ArrayLike, y: ArrayLike, final: float) -> tuple[float, float]:
    """(time constant, settling time) [s] of ``y`` moving from ``y[0]`` to ``final``."""
    t = np.asarray(t_s, dtype=float)
    y = np.asarray(y, dtype=float)
    change = final - y[0]
    if abs(change) < NO_SPIN_RAD_S:
        return 0.0, 0.0
    progress = (y - y[0]) / change
    reached = np.nonzero(progress >= TIME_CONSTANT_FRACTION)[0]
    tau = float(t[reached[0]]) if reached.size else math.nan
    outside = np.nonzero(np.abs(y - final) > SETTLING_BAND * abs(change))[0]
    if outside.size == 0:
        settling = 0.0
    elif outside[-1] == len(t) - 1:
        settling = math.nan
    else:
        settling = float(t[outside[-1] + 1])
    return tau, settling


def _spin_alignment(w_rad_s: NDArray[np.float64]) -> float:
    """``|w_y| / |w|``; 0 when ``|w|`` is below ``NO_SPIN_RAD_S`` (no axis to align)."""
    norm = float(np.linalg.norm(w_rad_s))
    return 0.0 if norm < NO_SPIN_RAD_S else float(abs(w_rad_s[1]) / norm)


def attitude_reference_series(
    series: RunSeries, w_ref_rad_s: ArrayLike, attitude_reference: str = "integrate_w_ref"
) -> NDArray[np.float64]:
    """(n, 4) attitude reference at every sample, made from the first sample (module docstring)."""
    w_ref = np.asarray(w_ref_rad_s, dtype=float)
    q0, propagate = attitude_reference_at_stamp(
        attitude_reference,
        series.orientation_wxyz[0],
        series.angular_velocity_rad_s[0],
        series.principal_inertia_kg_m2[0],
        w_ref,
    )
    rate = w_ref if propagate else np.zeros(3)
    return np.array([propagate_attitude(q0, rate, float(t - series.t_s[0])) for t in series.t_s])


def attitude_error_rad(
    series: RunSeries, w_ref_rad_s: ArrayLike, attitude_reference: str = "integrate_w_ref"
) -> NDArray[np.float64]:
    """Angle [rad] between the attitude and :func:`attitude_reference_series`."""
    refs = attitude_reference_series(series, w_ref_rad_s, attitude_reference)
    q = series.orientation_wxyz / np.linalg.norm(series.orientation_wxyz, axis=1, keepdims=True)
    dot = np.clip(np.abs(np.sum(q * refs, axis=1)), 0.0, 1.0)
    return 2.0 * np.arccos(dot)


def flight_summary(
    series: RunSeries,
    paper: Mapping[str, Any] | None = None,
    w_ref_rad_s: ArrayLike = (0.0, 1.0, 0.0),
    attitude_reference: str = "integrate_w_ref",
) -> dict[str, Metric]:
    """The paper's spin-stabilisation figures (and attitude error) of a run."""
    paper = dict(paper or {})
    w = series.angular_velocity_rad_s
    final = _final_mask(series)
    wy_final = float(np.mean(w[final, 1]))
    tau, settling = step_response(series.t_s, w[:, 1], wy_final)
    energy = _rotational_energy(series)
    momentum = _momentum_norm(series)
    iyy_end = float(series.principal_inertia_kg_m2[-1, 1])
    w_end = w[-1]
    att = attitude_error_rad(series, w_ref_rad_s, attitude_reference)
    window = f"mean over the last {FINAL_WINDOW_S:g} s"
    energy_paper = paper.get("energy")
    out = {
        "residual_wx": Metric(
            float(np.mean(np.abs(w[final, 0]))),
            "rad/s",
            f"|w_x|, {window}",
            paper.get("residual_wx"),
        ),
        "residual_wz": Metric(
            float(np.mean(np.abs(w[final, 2]))),
            "rad/s",
            f"|w_z|, {window}",
            paper.get("residual_wz"),
        ),
        "wy_final": Metric(wy_final, "rad/s", f"w_y, {window}", paper.get("wy_final")),
        "wy_from_momentum": Metric(
            float(momentum[-1] / iyy_end),
            "rad/s",
            "|H| / Iyy at the end: the spin rate conservation of H allows about y",
        ),
        "time_constant_s": Metric(
            tau, "s", "first time w_y covers 63.2 % of its change", paper.get("time_constant_s")
        ),
        "settling_time_s": Metric(
            settling,
            "s",
            f"w_y within {SETTLING_BAND:.0%} of its change from then on",
            paper.get("settling_time_s"),
        ),
        "max_g": Metric(
            float(np.max(_hemi_g(series))),
            "G",
            "largest specific force on a hemi body",
            paper.get("max_g"),
        ),
        "energy_start_j": Metric(float(energy[0]), "J", "1/2 w'Iw at t = 0", energy_paper),
        "energy_end_j": Metric(float(energy[-1]), "J", "1/2 w'Iw at the end", energy_paper),
        "momentum_start": Metric(float(momentum[0]), "kg m^2/s", "|H| at t = 0"),
        "momentum_end": Metric(float(momentum[-1]), "kg m^2/s", "|H| at the end"),
        "spin_alignment_final": Metric(
            _spin_alignment(w_end), "-", "|w_y| / |w| at the end (0 without a spin)"
        ),
        "attitude_error_final_deg": Metric(
            float(np.degrees(np.mean(att[final]))),
            "deg",
            f"angle to the attitude reference, {window}",
        ),
        "max_horizontal_speed_m_s": Metric(
            float(np.max(np.linalg.norm(series.velocity_m_s[:, :2], axis=1))),
            "m/s",
            "largest horizontal speed of the centre of mass (jumping flight)",
            paper.get("horizontal_speed_mps"),
        ),
        "radii_range_m": Metric(
            float(np.max(np.ptp(series.radii_m, axis=0))), "m", "largest range of r_x, r_y, r_z"
        ),
        "inertia_range_kg_m2": Metric(
            float(np.max(np.ptp(series.principal_inertia_kg_m2, axis=0))),
            "kg m^2",
            "largest range of Ixx, Iyy, Izz",
        ),
        "w_tracking_rms_rad_s": Metric(
            w_tracking_rms(series.t_s, w, w_ref_rad_s),
            "rad/s",
            "RMS of |w - w_ref| over the run",
        ),
    }
    for key, text in (
        ("mpc_failures", "MPC solves not executed (failed, late or missed deadline)"),
        ("mpc_deadline_misses", "MPC solves abandoned at their wall-time deadline"),
    ):
        counts = series.extras.get(key)
        if counts is not None and len(counts):
            out[key] = Metric(float(np.nanmax(counts)), "-", text)
    return out


def w_tracking_rms(t_s: ArrayLike, w_rad_s: ArrayLike, w_ref_rad_s: ArrayLike) -> float:
    """Time-weighted (trapezoidal) RMS of ``|w - w_ref|`` [rad/s] over ``t_s``."""
    t = np.asarray(t_s, dtype=float)
    error_sq = np.sum((np.asarray(w_rad_s, dtype=float) - np.asarray(w_ref_rad_s)) ** 2, axis=1)
    if t.size < 2 or t[-1] <= t[0]:
        return float(np.sqrt(error_sq[0])) if error_sq.size else math.nan
    return float(np.sqrt(np.trapezoid(error_sq, t) / (t[-1] - t[0])))


@dataclass(frozen=True)
class FindingResult:
    """A paper finding checked on this project's runs (``reproduced`` None: a variant not run)."""

    statement: str
    metric: str
    expectation: str
    values: dict[str, float]
    reproduced: bool | None

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def evaluate_findings(
    findings: Sequence[PaperFinding], metrics_by_variant: Mapping[str, Mapping[str, Metric]]
) -> list[FindingResult]:
    """Each finding's comparison on the variants that ran; ``KeyError`` names a missing metric."""
    results = []
    for finding in findings:
        values: dict[str, float] = {}
        for variant in (finding.variant, finding.other):
            if variant in metrics_by_variant:
                metrics = metrics_by_variant[variant]
                if finding.metric not in metrics:
                    raise KeyError(f"finding {finding.statement!r}: no metric {finding.metric!r}")
                values[variant] = metrics[finding.metric].value
        reproduced = None
        if len(values) == 2:
            left, right = values[finding.variant], values[finding.other]
            reproduced = bool(left > right if finding.relation == ">" else left < right)
        results.append(
            FindingResult(
                finding.statement, finding.metric, finding.expectation, values, reproduced
            )
        )
    return results


def summary_table(metrics: Mapping[str, Metric]) -> list[tuple[str, str, str, str]]:
    """Rows (name, value, unit, paper) for printing."""
    rows = []
    for name, m in metrics.items():
        value = "" if math.isnan(m.value) else f"{m.value:.4g}"
        paper = "" if m.paper is None else str(m.paper)
        rows.append((name, value, m.unit, paper))
    return rows
