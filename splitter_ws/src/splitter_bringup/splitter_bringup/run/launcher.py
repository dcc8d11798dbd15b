"""Launch the node graph of a scenario, one process per node, and run it to its end.

The simulator is started last: in lockstep it waits until the controllers and
the recorder are connected, then runs the scenario and exits at its end; the
launcher then stops every other node, the recorder last (it takes what the others
published until they exited, then closes its bag).
Ctrl-C or SIGTERM stop every child cleanly.

A ``graph_watchdog`` node (:mod:`splitter_bringup.nodes.graph_watchdog_node`) watches
the progress of every node of the data path and names a stalled one:

* lockstep: a node that dies, or one that makes no progress for ``stall_timeout_s``
  (wall), ends the run: the error names it, every other node is stopped (the
  recorder last, so the bag is finalized) and the launch fails (``died:<node>`` or
  ``stalled:<node>``). The simulator's own lockstep timeout is set well above it.
* real time: a dead or stalled node is reported (logged, and listed in
  :attr:`LaunchResult.incidents`) while the rest keeps running: the simulator
  holds the last good joint commands, the allocator the last good setpoint. Only
  the simulator's end, its death, the recorder's death or a stop end the run.

The watchdog also reports publishers on the graph's topics that the launcher did not
start (``FOREIGN publisher ...``; :attr:`LaunchResult.foreign_publishers`).

Isolation: the graph runs on the ROS domain the user named (``domain_id``, else
``ROS_DOMAIN_ID``), or else on one no other graph on this machine uses
(:func:`splitter_msgs_py.domains.choose_domain`), held for the whole run. It is
logged and written to ``out_dir/domain_id``. Every node is started with
``SPLITTER_PARENT_PID`` (it dies with the launcher, however the launcher ends:
:mod:`splitter_msgs_py.lifetime`) and ``SPLITTER_RUN_DIR`` (the run's folder).
"""

from __future__ import annotations

import logging
import os
import re
import sys
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from splitter_bringup.analysis.foreign_publishers import FOREIGN_PREFIX
from splitter_bringup.analysis.watchdog import DEFAULT_STALL_TIMEOUT_S, PROGRESS_TOPICS
from splitter_bringup.run.processes import (
    ProcessSpec,
    Supervisor,
    install_stop_handlers,
    node_argv,
)
from splitter_bringup.scenario.definition import Scenario
from splitter_bringup.scenario.graph_config import (
    NodeLaunch,
    graph_nodes,
    ground_parameters,
    with_parameter_attachments,
    write_parameter_file,
)
from splitter_msgs_py.domains import DomainChoice, choose_domain
from splitter_msgs_py.environment import ros_environment
from splitter_msgs_py.lifetime import PARENT_PID_ENV

LOG = logging.getLogger(__name__)
# [s] after the simulator's last step, time for the recorder to receive what is in flight
DRAIN_S = 1.5
_PROGRESS = re.compile(r"t = ([0-9.]+) s")
_STALLED = re.compile(r"STALLED (\w+): (.*)")
_FOREIGN = re.compile(rf"{FOREIGN_PREFIX} publisher (\S+) on (\S+): (.*)")
RUN_DIR_ENV = "SPLITTER_RUN_DIR"  # every node's environment names its run folder
DOMAIN_FILE = "domain_id"  # in the run folder: the ROS domain the graph ran on
WATCHDOG = "graph_watchdog"
FOXGLOVE_BRIDGE = "foxglove_bridge"
# the simulator steps on after this many stall timeouts only when no watchdog ends the run
SIMULATOR_TIMEOUT_FACTOR = 3.0
# a death that does not end a real-time run (the graph keeps running without it)
SURVIVABLE_IN_REAL_TIME = ("inertial_morphing_mpc", "ik_tether_allocator", "gait_phase_manager")


@dataclass(frozen=True)
class LaunchResult:
    """How a launch ended."""

    outcome: str  # "ended", "stopped", "timeout", "died:<node>" or "stalled:<node>"
    exit_codes: dict[str, int | None]
    bag_dir: Path | None
    incidents: tuple[str, ...] = ()  # real time: nodes reported dead or stalled
    domain_id: int | None = None  # the ROS domain the graph ran on
    foreign_publishers: tuple[str, ...] = ()  # "<node> on <topic>" the graph did not start

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
    stall_timeout_s: float = DEFAULT_STALL_TIMEOUT_S,
    quiet: bool = False,
    on_progress: Callable[[float], None] | None = None,
    foxglove_port: int | None = None,
    foxglove_host: str = "127.0.0.1",
) -> LaunchResult:
    """Run ``scenario`` through the node graph; records ``out_dir/bag`` when ``record``.

    ``stall_timeout_s``: wall time without progress after which the watchdog names a
    node stalled (module doc). ``foxglove_port``: also serve the graph to Foxglove on
    ``ws://foxglove_host:foxglove_port`` (:mod:`splitter_bringup.nodes.foxglove_bridge_node`).
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    with choose_domain(domain_id) as domain:
        record_domain(domain, out_dir)
        return _launch(
            scenario,
            out_dir,
            domain.domain_id,
            real_time=real_time,
            rate_factor=rate_factor,
            record=record,
            multi_host=multi_host,
            timeout_s=timeout_s,
            stall_timeout_s=stall_timeout_s,
            quiet=quiet,
            on_progress=on_progress,
            foxglove_port=foxglove_port,
            foxglove_host=foxglove_host,
        )


def record_domain(domain: DomainChoice, out_dir: Path) -> None:
    """Log the run's domain and write it to ``out_dir/domain_id`` (for those who join)."""
    LOG.info("%s (written to %s)", domain.describe(), out_dir / DOMAIN_FILE)
    (out_dir / DOMAIN_FILE).write_text(f"{domain.domain_id}\n", encoding="utf-8")


def _launch(
    scenario: Scenario,
    out_dir: Path,
    domain_id: int,
    *,
    real_time: bool,
    rate_factor: float,
    record: bool,
    multi_host: bool,
    timeout_s: float | None,
    stall_timeout_s: float,
    quiet: bool,
    on_progress: Callable[[float], None] | None,
    foxglove_port: int | None,
    foxglove_host: str,
) -> LaunchResult:
    bag_dir = out_dir / "bag" if record else None
    env = ros_environment(domain_id=domain_id, multi_host=multi_host)
    env["PYTHONUNBUFFERED"] = "1"
    env[PARENT_PID_ENV] = str(os.getpid())
    env[RUN_DIR_ENV] = str(out_dir.resolve())
    nodes = graph_nodes(scenario, real_time=real_time, rate_factor=rate_factor, bag_dir=bag_dir)
    nodes = _with_watchdog(nodes, real_time, stall_timeout_s)
    if foxglove_port is not None:
        nodes = _with_foxglove(nodes, foxglove_host, foxglove_port, ground_parameters(scenario))
    nodes = _watchdog_knows(nodes)
    nodes = with_parameter_attachments(nodes)  # the bag carries every node's parameters
    incidents: list[str] = []
    foreign: list[str] = []

    def on_line(name: str, line: str) -> None:
        match = _PROGRESS.search(line) if name == "simulator" else None
        if match and on_progress is not None:
            on_progress(float(match.group(1)))
        if not quiet:
            print(f"[{name}] {line}", file=sys.stderr, flush=True)
        found = _FOREIGN.search(line) if name == WATCHDOG else None
        if found:
            node, topic, reason = found.groups()
            LOG.warning("a publisher the graph did not start: %s on %s (%s)", node, topic, reason)
            foreign.append(f"{node} on {topic}")
        stalled = _STALLED.search(line) if name == WATCHDOG else None
        if stalled:
            node, reason = stalled.groups()
            if real_time:
                LOG.error("%s makes no progress (%s): the rest keeps running", node, reason)
                incidents.append(f"stalled:{node}")
            else:
                LOG.error("%s makes no progress (%s): stopping the graph", node, reason)
                supervisor.fail(f"stalled:{node}")

    supervisor = Supervisor(on_line=on_line, log_dir=out_dir / "logs")
    restore = install_stop_handlers(supervisor)
    try:
        for node in nodes:
            params = write_parameter_file(node, out_dir / "params")
            supervisor.start(
                ProcessSpec(
                    node.name,
                    node_argv(
                        node.entry,
                        params,
                        ["-r", f"__node:={node.name}", *node.remapping_args()],
                    ),
                    env,
                    ends_run=node.name == "simulator",
                    stops_last=node.name == "recorder",
                )
            )
        outcome, code = _wait(supervisor, timeout_s, real_time, incidents)
        supervisor.stop_one(WATCHDOG)  # the end is decided: a stopping graph is no stall
        if outcome == "ended":
            time.sleep(DRAIN_S)
        if outcome.startswith("died:"):
            LOG.error("%s exited with code %s: stopping the graph", outcome[5:], code)
        elif outcome == "timeout":
            LOG.error("the run did not end within %.0f s: stopping the graph", timeout_s or 0.0)
        codes = supervisor.stop_all()
    finally:
        restore()
    return LaunchResult(outcome, codes, bag_dir, tuple(incidents), domain_id, tuple(foreign))


def _watchdog_knows(nodes: list[NodeLaunch]) -> list[NodeLaunch]:
    """``nodes`` with the watchdog told every node name of the graph (foreign publishers)."""
    names = [n.name for n in nodes]
    return [
        replace(n, parameters={**n.parameters, "graph_nodes": names}) if n.name == WATCHDOG else n
        for n in nodes
    ]


def _with_watchdog(
    nodes: list[NodeLaunch], real_time: bool, stall_timeout_s: float
) -> list[NodeLaunch]:
    """``nodes`` with the watchdog before the simulator, whose lockstep timeout it undercuts."""
    watched = [n.name for n in nodes if n.name in PROGRESS_TOPICS]
    watchdog = NodeLaunch(
        WATCHDOG,
        "splitter_bringup.nodes.graph_watchdog_node:main",
        "splitter_bringup.nodes.graph_watchdog_node:GraphWatchdogNode",
        {
            "watched_nodes": watched,
            "lockstep": not real_time,
            "stall_timeout_s": float(stall_timeout_s),
        },
    )
    out = []
    for node in nodes:
        if node.name == "simulator":
            out.append(watchdog)
            timeout = SIMULATOR_TIMEOUT_FACTOR * float(stall_timeout_s)
            out.append(replace(node, parameters={**node.parameters, "lockstep_timeout_s": timeout}))
        else:
            out.append(node)
    return out


def _with_foxglove(
    nodes: list[NodeLaunch], host: str, port: int, ground: Mapping[str, Any]
) -> list[NodeLaunch]:
    """``nodes`` with the Foxglove bridge before the simulator (it sees the run from its start).

    ``ground``: the scenario's ground parameters
    (:func:`~splitter_bringup.scenario.graph_config.ground_parameters`), drawn by the bridge.
    """
    bridge = NodeLaunch(
        FOXGLOVE_BRIDGE,
        "splitter_bringup.nodes.foxglove_bridge_node:main",
        "splitter_bringup.nodes.foxglove_bridge_node:FoxgloveBridgeNode",
        {"use_sim_time": True, "host": host, "port": int(port), **ground},
    )
    out = [n for n in nodes if n.name != "simulator"]
    return [*out, bridge, *(n for n in nodes if n.name == "simulator")]


def _wait(
    supervisor: Supervisor, timeout_s: float | None, real_time: bool, incidents: list[str]
) -> tuple[str, int | None]:
    """The run's outcome; in real time a controller's death is reported, not an end."""
    deadline = None if timeout_s is None else time.monotonic() + timeout_s
    dead: set[str] = set()
    while True:
        remaining = None if deadline is None else max(0.0, deadline - time.monotonic())
        outcome, code = supervisor.wait(timeout_s=remaining, ignore=dead)
        node = outcome[5:] if outcome.startswith("died:") else ""
        if not (real_time and node in SURVIVABLE_IN_REAL_TIME):
            return outcome, code
        LOG.error("%s exited with code %s: the rest keeps running", node, code)
        incidents.append(outcome)
        dead.add(node)
