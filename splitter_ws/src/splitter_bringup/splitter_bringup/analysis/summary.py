"""The figures of one variant's run: what ``splitter run`` prints and compares, in one place.

ROS-free.
"""

from __future__ import annotations

import math

from splitter_bringup.analysis.jump_metrics import gait_summary, jumping_summary
from splitter_bringup.analysis.metrics import Metric, flight_summary
from splitter_bringup.analysis.series import RunSeries
from splitter_bringup.scenario.definition import Scenario


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
            **metrics,
        }
        metrics.pop("max_horizontal_speed_m_s", None)
    return metrics


def metric_values(series: RunSeries, scenario: Scenario) -> dict[str, float]:
    """The finite numbers of :func:`variant_metrics`, by name (what two runs are compared on)."""
    return {
        k: float(m.value)
        for k, m in variant_metrics(series, scenario).items()
        if isinstance(m.value, int | float) and math.isfinite(float(m.value))
    }
