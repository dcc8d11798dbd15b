"""``splitter launch --in-process``: the node graph of a scenario in this one process.

The same node classes and parameters as the launcher's processes
(:func:`~splitter_bringup.scenario.graph_config.graph_nodes`, the recorder included),
created in one rclpy context on the loopback-only DDS profile and spun by one
executor (:mod:`splitter_msgs_py.executors`). They still talk over their DDS
topics, so the bag, Foxglove and ``ros2 topic`` see the same graph; what goes away
is one Python interpreter, one DDS participant and one UDP hop per node. The
MPC's solver keeps its own worker process.

The run ends when the simulator reaches ``duration_s``: the recorder then takes
what is still queued and closes its bag. There is no watchdog (a stalled node
stalls the whole process): a lockstep wait is bounded by the simulator's
``lockstep_timeout_s``, the whole run by ``timeout_s``. Publishers on the graph's
topics that the graph did not create are reported as by the launcher's watchdog
(:mod:`splitter_bringup.analysis.foreign_publishers`).

The ROS domain is chosen as by the launcher (:func:`splitter_msgs_py.domains.choose_domain`)
and written to ``out_dir/domain_id``; this process's ``ROS_DOMAIN_ID`` is set for the run
and restored after it.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import rclpy
from rclpy.executors import Executor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from splitter_bringup.analysis.foreign_publishers import ForeignPublisherTracker
from splitter_bringup.nodes.graph_watchdog_node import graph_publishers
from splitter_bringup.run.inprocess import create_node
from splitter_bringup.run.launcher import LaunchResult, record_domain
from splitter_bringup.scenario.definition import Scenario
from splitter_bringup.scenario.graph_config import (
    graph_nodes,
    with_parameter_attachments,
    write_parameter_file,
)
from splitter_msgs_py.domains import choose_domain
from splitter_msgs_py.environment import ros_environment
from splitter_msgs_py.executors import make_executor
from splitter_msgs_py.signals import StopRequest, drain, flush_publishers
from splitter_sim.simulator_node import SimulatorNode

LOG = logging.getLogger(__name__)
SPIN_PERIOD_S = 0.1  # [s] longest wait for work before the end and stop are checked again
PROGRESS_PERIOD_S = 1.0  # [s] of simulated time between two progress reports
FOREIGN_CHECK_PERIOD_S = 1.0  # [s] wall, between two looks for foreign publishers
RECORDER = "recorder"
SIMULATOR = "simulator"


def launch_in_process(
    scenario: Scenario,
    out_dir: Path,
    *,
    real_time: bool = False,
    rate_factor: float = 1.0,
    record: bool = True,
    multi_host: bool = False,
    domain_id: int | None = None,
    timeout_s: float | None = None,
    on_progress: Callable[[float], None] | None = None,
) -> LaunchResult:
    """Run ``scenario`` through its node graph in this process; records ``out_dir/bag``.

    The parameters each node got are written to ``out_dir/params`` as for a
    launch with processes. The DDS environment (loopback-only unless
    ``multi_host``) is set in this process before its rclpy context starts.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    previous_domain = os.environ.get("ROS_DOMAIN_ID")
    with choose_domain(domain_id) as domain:
        record_domain(domain, out_dir)
        try:
            os.environ.update(ros_environment(domain_id=domain.domain_id, multi_host=multi_host))
            result = _launch_in_process(
                scenario,
                out_dir,
                real_time=real_time,
                rate_factor=rate_factor,
                record=record,
                timeout_s=timeout_s,
                on_progress=on_progress,
            )
        finally:
            if previous_domain is None:
                os.environ.pop("ROS_DOMAIN_ID", None)
            else:
                os.environ["ROS_DOMAIN_ID"] = previous_domain
    return replace(result, domain_id=domain.domain_id)


def _launch_in_process(
    scenario: Scenario,
    out_dir: Path,
    *,
    real_time: bool,
    rate_factor: float,
    record: bool,
    timeout_s: float | None,
    on_progress: Callable[[float], None] | None,
) -> LaunchResult:
    bag_dir = out_dir / "bag" if record else None
    nodes = graph_nodes(scenario, real_time=real_time, rate_factor=rate_factor, bag_dir=bag_dir)
    nodes = with_parameter_attachments(nodes)  # the bag carries every node's parameters
    for node in nodes:
        write_parameter_file(node, out_dir / "params")
    stop = StopRequest()
    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    created: dict[str, Node] = {}
    outcome = "ended"
    foreign = ForeignPublisherTracker([node.name for node in nodes])
    try:
        executor = make_executor(context)
        for node in nodes:  # the recorder first, the simulator last
            created[node.name] = create_node(node, context)
            executor.add_node(created[node.name])
        simulator = created[SIMULATOR]
        outcome = _spin(executor, simulator, stop, timeout_s, on_progress, foreign=foreign)
        # the simulator stops stepping; the controllers answer its last state and the
        # recorder takes what is still queued for it
        for timer in simulator.timers:
            timer.cancel()
        executor.remove_node(simulator)
        recorder = created.get(RECORDER)
        if recorder is not None and context.ok():
            late = drain(executor, lambda: sum(recorder.message_counts.values()))
            LOG.info("recorder: drained %d messages still queued at the end", late)
        for node in created.values():
            if node.context.ok():
                flush_publishers(node)
    finally:
        for name in reversed(list(created)):  # the simulator first, the recorder last
            created[name].destroy_node()
        context.try_shutdown()
    codes: dict[str, int | None] = {name: 0 for name in created}
    found = tuple(f"{f.node} on {f.topic}" for f in foreign.found)
    return LaunchResult(outcome, codes, bag_dir, foreign_publishers=found)


def _spin(
    executor: Executor,
    simulator: SimulatorNode,
    stop: StopRequest,
    timeout_s: float | None,
    on_progress: Callable[[float], None] | None,
    *,
    foreign: ForeignPublisherTracker,
) -> str:
    """Execute callbacks until the simulator finishes ("ended"), a stop or the timeout;
    every :data:`FOREIGN_CHECK_PERIOD_S` log the new publishers the graph did not create."""
    deadline = None if timeout_s is None else time.monotonic() + timeout_s
    next_report_ns = 0
    next_foreign_check = time.monotonic()
    while not simulator.finished.done():
        if time.monotonic() >= next_foreign_check:
            next_foreign_check = time.monotonic() + FOREIGN_CHECK_PERIOD_S
            for found in foreign.update(graph_publishers(simulator)):
                LOG.warning("a publisher the graph did not start: %s", found.line())
        if stop.requested:
            LOG.info("%s: stopping the graph", stop.signal_name)
            return "stopped"
        if deadline is not None and time.monotonic() > deadline:
            LOG.error("the run did not end within %.0f s: stopping the graph", timeout_s)
            return "timeout"
        executor.spin_once(timeout_sec=SPIN_PERIOD_S)
        t_ns = simulator.time_ns
        if on_progress is not None and t_ns >= next_report_ns:
            on_progress(t_ns * 1e-9)
            next_report_ns = t_ns + round(PROGRESS_PERIOD_S * 1e9)
    if on_progress is not None:
        on_progress(simulator.time_ns * 1e-9)
    return "ended"
