"""A jumping campaign's draw flown: every variant of the draw's world, judged.

What a campaign worker runs for ``splitter campaign lunar_jumping``
(:func:`run_jump_draw`, through the run interface
:func:`splitter_bringup.run.backends.run`); the draws, the judging and the
statistics are :mod:`splitter_bringup.analysis.jump_campaign`. ROS-free.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping

from splitter_bringup.analysis.jump_campaign import (
    JumpDraw,
    JumpDrawResult,
    LandingOutcome,
    classify_landing,
    error_outcome,
    scenario_for_jump_draw,
)
from splitter_bringup.analysis.series import RunSeries
from splitter_bringup.run.backends import LIBRARY, run
from splitter_bringup.run.campaign import campaign_mpc
from splitter_bringup.scenario.definition import Scenario

_LOG = logging.getLogger(__name__)


def fly_jump_draw(base: Scenario, draw: JumpDraw, solver: str | None = None) -> RunSeries:
    """The library closed loop of one variant (``base``) in the draw's world: a fresh
    controller and solver worker, the controllers on the flight estimator; ``solver``:
    the MPC back-end (None: the default one)."""
    return run(scenario_for_jump_draw(base, draw), LIBRARY, mpc=campaign_mpc(solver))


def run_jump_draw(
    variants: Mapping[str, Scenario], draw: JumpDraw, solver: str | None = None
) -> JumpDrawResult:
    """Fly the draw with every variant and judge each flight; never raises (an exception
    is that variant's ``error`` outcome)."""
    started = time.monotonic()
    outcomes: dict[str, LandingOutcome] = {}
    for name, base in variants.items():
        try:
            series = fly_jump_draw(base, draw, solver)
            outcomes[name] = classify_landing(
                series, scenario_for_jump_draw(base, draw), base.leg_cone_half_angle_deg
            )
        except Exception as exc:  # a failing flight is a result, not a crash of the campaign
            _LOG.warning("draw %d (seed %d), %s raised: %s", draw.index, draw.seed, name, exc)
            outcomes[name] = error_outcome(repr(exc))
    return JumpDrawResult(draw, outcomes, time.monotonic() - started)


def jump_error_result(
    draw: JumpDraw, variants: Mapping[str, Scenario], message: str
) -> JumpDrawResult:
    """Every variant's ``error`` outcome (the task's worker died)."""
    return JumpDrawResult(draw, {name: error_outcome(message) for name in variants})
