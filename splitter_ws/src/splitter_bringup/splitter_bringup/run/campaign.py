"""A campaign draw flown: the library closed loop of a draw's scenario, classified.

What a campaign worker runs (:mod:`splitter_bringup.cli.campaign` runs it on Dask);
the draws, the classification and the statistics are :mod:`splitter_bringup.analysis.campaign`.
ROS-free.
"""

from __future__ import annotations

import logging
import time

from splitter_bringup.analysis.campaign import (
    Draw,
    DrawResult,
    PerturbationSpec,
    draw_result,
    error_result,
    plant_model,
)
from splitter_bringup.scenario.definition import Scenario

_LOG = logging.getLogger(__name__)


def flight_perturbation(draw: Draw, spec: PerturbationSpec | None):
    """The closed loop's :class:`~splitter_bringup.core.closed_loop.Perturbation` of a draw.

    None when ``spec`` perturbs nothing (the nominal closed loop, bit for bit).
    """
    from splitter_bringup.core.closed_loop import Perturbation

    if spec is None or not spec.active:
        return None
    return Perturbation(
        plant_model=plant_model(draw) if spec.mass_fraction > 0.0 else None,
        gyro_noise_rad_s=spec.gyro_noise_rad_s,
        gyro_bias_rad_s=draw.gyro_bias_rad_s,
        actuator_lag_s=spec.actuator_lag_s,
        seed=draw.noise_seed,
    )


def fly_draw(scenario: Scenario, draw: Draw, perturbation: PerturbationSpec | None = None):
    """The :class:`~splitter_bringup.analysis.series.RunSeries` of a draw's flight.

    ``scenario`` is already set to the draw (:func:`scenario_for_draw`). The library
    closed loop with the scenario's MPC, a fresh controller and solver worker, so that
    a draw never depends on the ones flown before it.
    """
    from splitter_bringup.core.closed_loop import run_closed_loop

    return run_closed_loop(scenario, perturbation=flight_perturbation(draw, perturbation))


def run_draw(
    scenario: Scenario,
    draw: Draw,
    perturbation: PerturbationSpec | None = None,
) -> DrawResult:
    """Fly a draw (:func:`fly_draw`) and classify it: what a campaign worker runs.

    Never raises: an exception becomes the ``error`` outcome.
    """
    started = time.monotonic()
    try:
        series = fly_draw(scenario, draw, perturbation)
    except Exception as exc:  # a failing draw is a result, not a crash of the campaign
        _LOG.warning("draw %d (seed %d) raised: %s", draw.index, draw.seed, exc)
        return error_result(draw, repr(exc), time.monotonic() - started)
    return draw_result(draw, series, time.monotonic() - started)
