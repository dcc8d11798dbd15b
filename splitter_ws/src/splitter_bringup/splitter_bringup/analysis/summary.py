"""The figures of one variant's run: what ``splitter run`` prints and compares, in one place.

ROS-free.
"""

from __future__ import annotations

import math

import numpy as np

from splitter_bringup.analysis.jump_metrics import gait_summary, jumping_summary
from splitter_bringup.analysis.metrics import Metric, flight_summary
from splitter_bringup.analysis.series import RunSeries
from splitter_bringup.analysis.touchdowns import touchdown_summary
from splitter_bringup.scenario.definition import Scenario
from splitter_model.model import RobotModel
from splitter_sim.core.robot_errors import RobotErrors

LAST_TICK_S = 0.01 - 1e-9  # [s] one control period before the end (the last commanded)


def variant_metrics(series: RunSeries, scenario: Scenario) -> dict[str, Metric]:
    """Flight figures, and the jumping figures for a scenario with jumps."""
    metrics = flight_summary(
        series,
        scenario.paper,
        scenario.controller.w_ref_rad_s,
        scenario.controller.attitude_reference,
    )
    if scenario.jumps:
        metrics = {
            **jumping_summary(series, scenario.jumps, scenario.paper),
            **gait_summary(series, len(scenario.jumps)),
            **touchdown_summary(
                series,
                scenario.leg_cone_half_angle_deg,
                plant_model(scenario),
                scenario.terrain,
            ),
            **metrics,
        }
        metrics.pop("max_horizontal_speed_m_s", None)
    if scenario.robot_errors.present and "estimate_gyro_bias_rad_s" in series.extras:
        metrics.update(estimator_metrics(series, scenario))
        bodies = any(scenario.robot_errors.hemi_inertia_kg_m2)
        if bodies or scenario.estimator.hemi_inertia_prior_kg_m2 > 0.0:
            metrics["estimator_hemi_inertia_error_kg_m2"] = Metric(
                hemi_inertia_error(series, scenario.robot_errors),
                "kg m^2",
                "|estimated - true| moment of a hemi body about the tether axis at the last "
                "control tick (the estimator's model has points unless it estimates it)",
            )
    return metrics


def plant_model(scenario: Scenario) -> RobotModel:
    """The simulated robot of ``scenario`` (its masses, ``robot_errors.mass_scale``)."""
    return scenario.robot_errors.plant_model(RobotModel())


def estimator_errors(series: RunSeries, errors: RobotErrors) -> tuple[float, float, float]:
    """(largest gyro bias error [rad/s], largest relative mass-ratio error [-], largest
    relative mass error [-]).

    The flight estimator's estimate at the last tick the controllers acted on (a
    graph's estimator also answers the final state, which its bag may or may not
    hold) against the simulated robot's ``errors``; NaN without an estimator.
    """
    if "estimate_gyro_bias_rad_s" not in series.extras or len(series) == 0:
        return math.nan, math.nan, math.nan
    acted = np.flatnonzero(series.extras["estimate_t_s"] <= series.t_s[-1] - LAST_TICK_S)
    if acted.size == 0:
        return math.nan, math.nan, math.nan
    k = int(acted[-1])
    plant = errors.plant_model(RobotModel())
    bias = np.asarray(series.extras["estimate_gyro_bias_rad_s"][k], dtype=float)
    ratios = np.asarray(series.extras["estimate_mass_ratios"][k], dtype=float)
    masses = np.asarray(series.extras["estimate_masses_kg"][k], dtype=float)
    true_masses = np.array([plant.body_mass_kg, plant.limb_mass_y_kg, plant.limb_mass_z_kg])
    true_ratios = true_masses[1:] / true_masses[0]
    return (
        float(np.max(np.abs(bias - np.asarray(errors.gyro_bias_rad_s)))),
        float(np.max(np.abs(ratios / true_ratios - 1.0))),
        float(np.max(np.abs(masses / true_masses - 1.0))),
    )


def hemi_inertia_error(series: RunSeries, errors: RobotErrors) -> float:
    """|estimated - true| own moment of a hemi body about the tether axis [kg m^2] at the
    last tick the controllers acted on (as :func:`estimator_errors`); NaN without one."""
    if "estimate_hemi_inertia_kg_m2" not in series.extras or len(series) == 0:
        return math.nan
    acted = np.flatnonzero(series.extras["estimate_t_s"] <= series.t_s[-1] - LAST_TICK_S)
    if acted.size == 0:
        return math.nan
    estimated = float(series.extras["estimate_hemi_inertia_kg_m2"][int(acted[-1])][0])
    return abs(estimated - errors.hemi_inertia_kg_m2[0])


def estimator_metrics(series: RunSeries, scenario: Scenario) -> dict[str, Metric]:
    """The flight estimator's errors (:func:`estimator_errors`) as summary figures."""
    bias_error, ratio_error, mass_error = estimator_errors(series, scenario.robot_errors)
    return {
        "estimator_gyro_bias_error_rad_s": Metric(
            bias_error,
            "rad/s",
            "largest |estimated - true| gyro bias component at the last control tick",
        ),
        "estimator_mass_ratio_error": Metric(
            ratio_error,
            "-",
            "largest relative error of the estimated m_y/m_x, m_z/m_x at the last control tick",
        ),
        "estimator_mass_error": Metric(
            mass_error,
            "-",
            "largest relative error of the estimated m_x, m_y, m_z at the last control tick",
        ),
    }


def metric_values(series: RunSeries, scenario: Scenario) -> dict[str, float]:
    """The finite numbers of :func:`variant_metrics`, by name (what two runs are compared on)."""
    return {
        k: float(m.value)
        for k, m in variant_metrics(series, scenario).items()
        if isinstance(m.value, int | float) and math.isfinite(float(m.value))
    }
