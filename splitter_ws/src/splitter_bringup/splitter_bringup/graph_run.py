"""Run one scenario variant through the full node graph and read its bag back.

``splitter run SCENARIO --backend graph`` uses it: the launcher starts every
node as its own process with the recorder, the run ends with the scenario, and
the recorded bag becomes the :class:`RunSeries` that the summary and the plots
are made from, exactly as for a library run.
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

from splitter_bringup.core.scenario import load_scenario
from splitter_bringup.core.series import RunSeries
from splitter_bringup.launcher import launch
from splitter_bringup.run_bag import read_run_series

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


def run_graph(
    scenario_name: str,
    variant: str | None,
    out_dir: Path,
    *,
    real_time: bool = False,
    verbose: bool = False,
    timeout_s: float = 1800.0,
) -> RunSeries:
    """Launch, record and read back one variant; raises :class:`GraphRunError` on failure."""
    scenario = load_scenario(scenario_name, variant)
    run_dir = out_dir / scenario.variant
    result = launch(
        scenario,
        run_dir,
        real_time=real_time,
        record=True,
        timeout_s=timeout_s,
        quiet=not verbose,
        on_progress=_progress_printer(f"{scenario.name}/{scenario.variant}", scenario.duration_s),
    )
    if not result.ok or result.bag_dir is None:
        logs = run_dir / "logs"
        raise GraphRunError(
            f"{scenario.name}/{scenario.variant}: {result.outcome}, exit codes "
            f"{result.exit_codes}; node logs in {logs}"
        )
    LOG.info("bag recorded in %s", result.bag_dir)
    return read_run_series(result.bag_dir, gravity_m_s2=scenario.gravity_m_s2)
