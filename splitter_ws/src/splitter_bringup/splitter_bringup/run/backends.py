"""One interface over the ways to execute a scenario variant: ``run(scenario, backend)``.

Backends (:data:`BACKENDS`):

* ``library``: the library closed loop in this process, no ROS
  (:func:`splitter_bringup.run.library.run_closed_loop`);
* ``processes``: the node graph, one process per node, recorded to a bag and read back
  (:func:`splitter_bringup.run.graph_run.run_graph_scenario` with the launcher);
* ``inprocess``: the same graph, every node in this one process on one executor.

Each returns the variant's :class:`~splitter_bringup.analysis.series.RunSeries`;
:func:`run_variant` also says where the wall time went and what the graph saw. The
Monte-Carlo campaign flies its draws through it (:mod:`splitter_bringup.run.campaign`).
The graph backends import rclpy only when chosen.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from splitter_bringup.analysis.series import RunSeries
from splitter_bringup.scenario.definition import Scenario

if TYPE_CHECKING:  # the library loop and the MPC load only when a run starts
    from splitter_bringup.run.library import ProgressCallback
    from splitter_mpc.core.estimator import EstimatorConfig
    from splitter_mpc.core.mpc import MpcSettings

LIBRARY = "library"
PROCESSES = "processes"
IN_PROCESS = "inprocess"
BACKENDS = (LIBRARY, PROCESSES, IN_PROCESS)


@dataclass(frozen=True)
class VariantRun:
    """A variant's run: its series and where its wall time went."""

    series: RunSeries
    startup_s: float  # [s] wall: before the first step (processes, solver load, discovery)
    flight_wall_time_s: float  # [s] wall: the flight itself
    # graph backends: the ROS domain, the foreign publishers and the nodes' timing report
    facts: dict[str, Any] = field(default_factory=dict)


def run_variant(
    scenario: Scenario,
    backend: str = LIBRARY,
    *,
    out_dir: Path | None = None,
    mpc: MpcSettings | None = None,
    estimator: bool | None = None,
    estimation: EstimatorConfig | None = None,
    progress: ProgressCallback | None = None,
    domain_id: int | None = None,
) -> VariantRun:
    """Run ``scenario`` (its chosen variant) on ``backend`` to its end.

    Library backend: ``mpc`` sets the MPC's solver options (None: the scenario's),
    ``estimator`` (None: as the graph, on with robot errors) and ``estimation`` set the
    flight estimator (:func:`~splitter_bringup.run.library.run_closed_loop`), ``progress``
    receives the fraction done. Graph backends: the run folder is ``out_dir/<variant>`` (bag, node
    logs, parameter files), ``domain_id`` None chooses a free ROS domain.
    """
    if backend == LIBRARY:
        return _run_library(scenario, mpc, progress, estimator, estimation)
    if backend not in BACKENDS:
        raise ValueError(f"backend {backend!r} is not one of {BACKENDS}")
    if out_dir is None:
        raise ValueError(f"the {backend} backend records a bag: it needs out_dir")
    if estimator is not None or mpc is not None or estimation is not None:
        raise ValueError("estimator, estimation and mpc settings are library-backend options")
    return _run_graph(scenario, out_dir, in_process=backend == IN_PROCESS, domain_id=domain_id)


def run(scenario: Scenario, backend: str = LIBRARY, **options: Any) -> RunSeries:
    """The variant's :class:`RunSeries` on ``backend`` (options of :func:`run_variant`)."""
    return run_variant(scenario, backend, **options).series


def _run_library(
    scenario: Scenario,
    mpc: MpcSettings | None,
    progress: ProgressCallback | None,
    estimator: bool | None = None,
    estimation: EstimatorConfig | None = None,
) -> VariantRun:
    from splitter_bringup.run.library import (
        controller_config,
        library_controller,
        run_closed_loop,
    )
    from splitter_model.model import RobotModel

    started = time.monotonic()
    model = RobotModel()
    config = controller_config(scenario, mpc, knows_robot=estimator)
    with library_controller(model, config) as controller:
        flying = time.monotonic()
        series = run_closed_loop(
            scenario,
            progress,
            model=model,
            controller=controller,
            estimator=estimator,
            estimation=estimation,
        )
    return VariantRun(series, flying - started, time.monotonic() - flying)


def _run_graph(
    scenario: Scenario, out_dir: Path, *, in_process: bool, domain_id: int | None
) -> VariantRun:
    from splitter_bringup.run.graph_run import WallTiming, run_graph_scenario
    from splitter_bringup.run.launcher import LaunchResult
    from splitter_bringup.run.run_bag import read_timing_report

    timing: list[WallTiming] = []
    results: list[LaunchResult] = []
    series = run_graph_scenario(
        scenario,
        out_dir,
        timing=timing,
        in_process=in_process,
        domain_id=domain_id,
        results=results,
    )
    result = results[0]
    facts: dict[str, Any] = {
        "domain_id": result.domain_id,
        "foreign_publishers": len(result.foreign_publishers),
    }
    if result.bag_dir is not None:
        # input latency per node, late commands, the tether: their last reports
        facts["timing"] = read_timing_report(result.bag_dir)
    return VariantRun(series, timing[0].startup_s, timing[0].flight_wall_time_s, facts)
