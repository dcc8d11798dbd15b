"""Launch the node graph of a scenario, one process per node, and run it to its end.

The simulator is started last: in lockstep it waits until the controllers and
the recorder are connected, then runs the scenario and exits at its end; the
launcher then stops every other node, the recorder last (it takes what the others
published until they exited, then closes its bag).
A node that dies makes the launch fail with a non-zero exit code; Ctrl-C or
SIGTERM stop every child cleanly.
"""

from __future__ import annotations

import logging
import re
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from splitter_bringup.core.graph_config import graph_nodes, write_parameter_file
from splitter_bringup.core.processes import (
    ProcessSpec,
    Supervisor,
    install_stop_handlers,
    node_argv,
)
from splitter_bringup.core.scenario import Scenario
from splitter_msgs_py.environment import ros_environment

LOG = logging.getLogger(__name__)
# [s] after the simulator's last step, time for the recorder to receive what is in flight
DRAIN_S = 1.5
_PROGRESS = re.compile(r"t = ([0-9.]+) s")


@dataclass(frozen=True)
class LaunchResult:
    """How a launch ended."""

    outcome: str  # "ended", "stopped", "timeout" or "died:<node>"
    exit_codes: dict[str, int | None]
    bag_dir: Path | None

    @property
    def ok(self) -> bool:
        """True when the scenario ran to its end and every node exited cleanly."""
        return self.outcome == "ended" and all(code == 0 for code in self.exit_codes.values())


def launch(
    scenario: Scenario,
    out_dir: Path,
    *,
    real_time: bool = False,
    rate_factor: float = 1.0,
    record: bool = True,
    multi_host: bool = False,
    domain_id: int | None = None,
    timeout_s: float | None = None,
    quiet: bool = False,
    on_progress: Callable[[float], None] | None = None,
) -> LaunchResult:
    """Run ``scenario`` through the node graph; records ``out_dir/bag`` when ``record``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    bag_dir = out_dir / "bag" if record else None
    env = ros_environment(domain_id=domain_id, multi_host=multi_host)
    env["PYTHONUNBUFFERED"] = "1"
    nodes = graph_nodes(scenario, real_time=real_time, rate_factor=rate_factor, bag_dir=bag_dir)

    def on_line(name: str, line: str) -> None:
        match = _PROGRESS.search(line) if name == "simulator" else None
        if match and on_progress is not None:
            on_progress(float(match.group(1)))
        if not quiet:
            print(f"[{name}] {line}", file=sys.stderr, flush=True)

    supervisor = Supervisor(on_line=on_line, log_dir=out_dir / "logs")
    restore = install_stop_handlers(supervisor)
    try:
        for node in nodes:
            params = write_parameter_file(node, out_dir / "params")
            supervisor.start(
                ProcessSpec(
                    node.name,
                    node_argv(node.entry, params, ["-r", f"__node:={node.name}"]),
                    env,
                    ends_run=node.name == "simulator",
                    stops_last=node.name == "recorder",
                )
            )
        outcome, code = supervisor.wait(timeout_s=timeout_s)
        if outcome == "ended":
            time.sleep(DRAIN_S)
        if outcome.startswith("died:"):
            LOG.error("%s exited with code %s: stopping the graph", outcome[5:], code)
        elif outcome == "timeout":
            LOG.error("the run did not end within %.0f s: stopping the graph", timeout_s or 0.0)
        codes = supervisor.stop_all()
    finally:
        restore()
    return LaunchResult(outcome, codes, bag_dir)
