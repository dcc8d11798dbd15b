"""Run one scenario variant through the full node graph and read its bag back.

``splitter run SCENARIO --backend graph`` uses it: the launcher starts every
node as its own process with the recorder (or, ``in_process``, creates them all in
this process: :mod:`splitter_bringup.run.inprocess_launch`), the run ends with the
scenario, and
the recorded bag becomes the :class:`RunSeries` that the summary and the plots
are made from, exactly as for a library run.
"""

from __future__ import annotations

import logging
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from splitter_bringup.analysis.series import RunSeries
from splitter_bringup.run.launcher import LaunchResult, launch
from splitter_bringup.run.run_bag import read_run_series, read_wall_timing
from splitter_bringup.scenario.definition import Scenario, load_scenario

LOG = logging.getLogger(__name__)


class GraphRunError(RuntimeError):
    """The graph did not run the scenario to its end."""


def _progress_printer(label: str, duration_s: float):
    last = [-1]

    def on_progress(t_s: float) -> None:
        percent = int(100 * min(1.0, t_s / duration_s))
        if percent // 10 != last[0]:
            last[0] = percent // 10
            print(
                f"  {label}: t = {t_s:5.2f} / {duration_s:.2f} s ({percent:3d} %)", file=sys.stderr
            )

    return on_progress


@dataclass(frozen=True)
class WallTiming:
    """Where a run's wall time went [s]: start-up (processes, solver load, discovery) and flight."""

    startup_s: float  # from the start of the run to the simulator's first step
    flight_wall_time_s: float  # the simulator's stepping, first step to the last


def run_graph(scenario_name: str, variant: str | None, out_dir: Path, **options: Any) -> RunSeries:
    """:func:`run_graph_scenario` of a scenario given by name (or path) and variant."""
    return run_graph_scenario(load_scenario(scenario_name, variant), out_dir, **options)


def run_graph_scenario(
    scenario: Scenario,
    out_dir: Path,
    *,
    real_time: bool = False,
    verbose: bool = False,
    timeout_s: float = 1800.0,
    timing: list[WallTiming] | None = None,
    in_process: bool = False,
    domain_id: int | None = None,
    results: list[LaunchResult] | None = None,
) -> RunSeries:
    """Launch, record and read back one variant; raises :class:`GraphRunError` on failure.

    The run folder is ``out_dir/<variant>``. ``timing``, when given, receives the run's
    :class:`WallTiming` (from the simulator's wall-time figures on /diagnostics);
    ``results`` the launch's :class:`~splitter_bringup.run.launcher.LaunchResult` (its
    ROS domain, foreign publishers). ``domain_id``: None chooses one as the launcher does.
    """
    run_dir = out_dir / scenario.variant
    launched_unix_s = time.time()
    on_progress = _progress_printer(f"{scenario.name}/{scenario.variant}", scenario.duration_s)
    if in_process:
        from splitter_bringup.run.inprocess_launch import launch_in_process

        result = launch_in_process(
            scenario,
            run_dir,
            real_time=real_time,
            timeout_s=timeout_s,
            on_progress=on_progress,
            domain_id=domain_id,
        )
    else:
        result = launch(
            scenario,
            run_dir,
            real_time=real_time,
            record=True,
            timeout_s=timeout_s,
            quiet=not verbose,
            on_progress=on_progress,
            domain_id=domain_id,
        )
    if results is not None:
        results.append(result)
    if not result.ok or result.bag_dir is None:
        logs = run_dir / "logs"
        raise GraphRunError(
            f"{scenario.name}/{scenario.variant}: {result.outcome}, exit codes "
            f"{result.exit_codes}; node logs in {logs}"
        )
    LOG.info("bag recorded in %s", result.bag_dir)
    if timing is not None:
        run_start_unix_s, flight_wall_time_s = read_wall_timing(result.bag_dir)
        timing.append(WallTiming(run_start_unix_s - launched_unix_s, flight_wall_time_s))
    return read_run_series(result.bag_dir, gravity_m_s2=scenario.gravity_m_s2)
