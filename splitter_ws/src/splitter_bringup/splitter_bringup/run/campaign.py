"""A campaign draw flown: the library closed loop of a draw's scenario, classified.

What a campaign worker runs (:func:`run_draw`, through the run interface
:func:`splitter_bringup.run.backends.run`), and the executor that runs every draw of a
campaign as a Dask task (:func:`run_on_dask`; ``splitter campaign`` calls it). The
draws, the classification and the statistics are :mod:`splitter_bringup.analysis.campaign`.
ROS-free.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any, TypeVar

from splitter_bringup.analysis.campaign import (
    Draw,
    DrawResult,
    PerturbationSpec,
    draw_result,
    error_result,
    estimator_for_draw,
    robot_errors_for_draw,
)
from splitter_bringup.analysis.series import RunSeries
from splitter_bringup.run.backends import LIBRARY, run
from splitter_bringup.scenario.definition import Scenario
from splitter_mpc.core.mpc import MpcSettings
from splitter_mpc.core.solvers import LOCKSTEP_MAX_TIME_S, SolverOptions

_LOG = logging.getLogger(__name__)
R = TypeVar("R")
_PROGRESS_LOG = logging.getLogger("splitter.campaign")
PROGRESS_STEP = 0.05  # a progress line per 5 % of the draws
# environment variables a worker takes from the process that starts the campaign
FORWARDED_ENV_PREFIXES = ("SPLITTER_",)
FORWARDED_ENV = ("MPLBACKEND", "PYTHONDONTWRITEBYTECODE", "ROS_DOMAIN_ID")


def campaign_mpc(solver: str | None) -> MpcSettings | None:
    """The MPC settings a campaign flies: the scenario's (None) or ``solver``'s, with the
    library loop's lockstep deadline (a slow solve is waited for)."""
    if solver is None:
        return None
    return MpcSettings(solver=solver, options=SolverOptions(max_time_s=LOCKSTEP_MAX_TIME_S))


def fly_draw(
    scenario: Scenario,
    draw: Draw,
    perturbation: PerturbationSpec | None = None,
    solver: str | None = None,
) -> RunSeries:
    """The :class:`~splitter_bringup.analysis.series.RunSeries` of a draw's flight.

    ``scenario`` is already set to the draw (:func:`scenario_for_draw`); the draw's
    robot errors (:func:`robot_errors_for_draw`) are flown by its simulator, and the
    controllers then fly on the flight estimator unless ``perturbation.estimator`` is
    False; with hemi bodies the estimator identifies their moments
    (:func:`estimator_for_draw`). The library backend
    (:func:`splitter_bringup.run.backends.run`): the closed loop with the scenario's MPC,
    a fresh controller and solver worker, so that a draw never depends on the ones flown
    before it. ``solver``: the MPC back-end (None: the default one).
    """
    spec = perturbation or PerturbationSpec()
    flown = replace(
        scenario,
        robot_errors=robot_errors_for_draw(draw, spec),
        fault_handling=spec.fault_handling,
    )
    if spec.estimator:
        flown = estimator_for_draw(flown, draw)
    return run(
        flown, LIBRARY, estimator=None if spec.estimator else False, mpc=campaign_mpc(solver)
    )


def run_draw(
    scenario: Scenario,
    draw: Draw,
    perturbation: PerturbationSpec | None = None,
    solver: str | None = None,
) -> DrawResult:
    """Fly a draw (:func:`fly_draw`) and classify it: what a campaign worker runs.

    Never raises: an exception becomes the ``error`` outcome.
    """
    started = time.monotonic()
    try:
        series = fly_draw(scenario, draw, perturbation, solver)
    except Exception as exc:  # a failing draw is a result, not a crash of the campaign
        _LOG.warning("draw %d (seed %d) raised: %s", draw.index, draw.seed, exc)
        return error_result(draw, repr(exc), time.monotonic() - started)
    return draw_result(draw, series, time.monotonic() - started)


# --- Dask ------------------------------------------------------------------------------
def _forwarded_environment() -> dict[str, str]:
    return {
        k: v
        for k, v in os.environ.items()
        if k in FORWARDED_ENV or k.startswith(FORWARDED_ENV_PREFIXES)
    }


def _worker_plugin_class():
    from distributed import WorkerPlugin

    class ProjectEnvironment(WorkerPlugin):
        """Sets the project's environment in every worker before it runs a draw.

        The process environment of ``splitter`` (``ros_environment``: loopback-only
        DDS, ``AMENT_PREFIX_PATH`` of the worker's Python) with the caller's
        ``SPLITTER_*``, ``MPLBACKEND``, ``PYTHONDONTWRITEBYTECODE`` and
        ``ROS_DOMAIN_ID``. The library backend needs no ROS; the solver worker
        processes a draw starts inherit this environment.
        """

        name = "splitter-environment"

        def __init__(self, forwarded: dict[str, str]) -> None:
            self.forwarded = dict(forwarded)

        def setup(self, worker) -> None:
            from splitter_msgs_py.environment import ros_environment

            env = ros_environment(base=dict(os.environ))
            env.update(self.forwarded)
            os.environ.update(env)

    return ProjectEnvironment


class _Progress:
    """A log line per ``PROGRESS_STEP`` of the draws, with the rate so far and the ETA."""

    def __init__(self, total: int) -> None:
        self.total = total
        self.done = 0
        self.successes = 0
        self.started = time.monotonic()
        self._next = PROGRESS_STEP

    def __call__(self, result: Any) -> None:
        self.done += 1
        self.successes += int(result.success)
        fraction = self.done / max(1, self.total)
        if fraction + 1e-12 < self._next and self.done < self.total:
            return
        while self._next <= fraction + 1e-12:
            self._next += PROGRESS_STEP
        elapsed = time.monotonic() - self.started
        eta = elapsed / self.done * (self.total - self.done)
        _PROGRESS_LOG.info(
            "%d/%d draws (%3.0f %%), %d successes, %.0f s elapsed, ETA %.0f s",
            self.done,
            self.total,
            100.0 * fraction,
            self.successes,
            elapsed,
            eta,
        )


def run_on_dask(
    jobs: Sequence[tuple[Scenario, Draw]],
    spec: PerturbationSpec,
    workers: int | None = None,
    scheduler: str | None = None,
    solver: str | None = None,
) -> tuple[list[DrawResult], dict[str, Any]]:
    """Every draw as a Dask task; (results in draw order, a description of the cluster)."""
    tasks = [
        (f"draw-{draw.index}-{draw.seed}", (scenario, draw, spec, solver))
        for scenario, draw in jobs
    ]
    draws = [draw for _, draw in jobs]

    def failed(k: int, exc: Exception) -> DrawResult:
        return error_result(draws[k], f"Dask task failed: {exc!r}")

    return map_on_dask(run_draw, tasks, failed, workers, scheduler)


def map_on_dask(
    function: Callable[..., R],
    tasks: Sequence[tuple[str, tuple]],
    failed: Callable[[int, Exception], R],
    workers: int | None = None,
    scheduler: str | None = None,
) -> tuple[list[R], dict[str, Any]]:
    """``function(*args)`` of every task ``(key, args)`` as a Dask task, with progress lines.

    An embedded ``LocalCluster`` on 127.0.0.1 (``workers`` processes of one thread,
    all cores by default, no dashboard) or the cluster at ``scheduler``. A task whose
    worker died gives ``failed(index, exception)``. The results have a ``success``
    attribute (counted in the progress lines). Returns (results in task order, a
    description of the cluster).
    """
    from distributed import Client, LocalCluster, as_completed

    progress = _Progress(len(tasks))
    # the scheduler's and the workers' chatter (INFO) would drown the progress lines
    logging.getLogger("distributed").setLevel(logging.WARNING)
    results: dict[int, R] = {}
    plugin = _worker_plugin_class()(_forwarded_environment())
    cluster = None
    if scheduler is None:
        n_workers = max(1, workers or os.cpu_count() or 1)
        cluster = LocalCluster(
            n_workers=n_workers,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            # no dashboard (bokeh is not installed); the scheduler's HTTP routes (health,
            # metrics) on a free loopback port: ":0" would listen on every interface
            dashboard_address="127.0.0.1:0",
        )
        client = Client(cluster)
    else:
        client = Client(scheduler)
    try:
        client.register_plugin(plugin)
        info = {
            "scheduler": client.scheduler.address,
            "embedded_local_cluster": cluster is not None,
            "workers": len(client.scheduler_info().get("workers", {})),
        }
        _PROGRESS_LOG.info(
            "%d draws on %d Dask workers (scheduler %s)",
            len(tasks),
            info["workers"],
            info["scheduler"],
        )
        futures, index_of = [], {}
        for k, (key, args) in enumerate(tasks):
            future = client.submit(function, *args, key=key, pure=False)
            futures.append(future)
            index_of[future.key] = k
        for future in as_completed(futures):
            k = index_of[future.key]
            try:
                result = future.result()
            except Exception as exc:  # the task's worker died: the draw is an error
                result = failed(k, exc)
            results[k] = result
            progress(result)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return [results[k] for k in range(len(tasks))], info
