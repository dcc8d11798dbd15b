"""``splitter bench graph``: real-time factor of the lockstep node graph, per scenario.

Each scenario's main variant is run through the lockstep graph, recorded to a bag
as ``splitter run`` does, in each mode (``processes``: every node its own
process; ``in-process``: all in one process on one executor), and through the
library loop. Printed for each: the flight's real-time factor (scenario seconds
over the wall time of the simulator's stepping, ``flight_wall_time_s``) beside
the goal (5x, issue 18), start-up apart (processes, solver load, discovery), and
the largest relative difference of the summary metrics between the two backends.

Beside them, what bounds the graph from below in one process: the *transport
floor* (:mod:`splitter_tools.transport_floor`: the graph's per-step messages
through rclpy with no computation) and the library loop's flight (the same
physics and control with no messages; the controller built beforehand, as the
graph builds it before its flight). Their sum is the fastest flight the graph could
reach with every node's own work (building, checking and recording messages)
free; ``ceiling_real_time_factor`` is the duration over it.

The CPU the graph costs: user + system seconds of this process and of every
process it started and waited for (the nodes, their solver workers), over the
graph run alone (start-up, flight and recording, not the library runs), and per
simulated second, beside issue 30's goal (at most 0.8 CPU-seconds per simulated
second plus 5 s of start-up, for ``splitter run lunar_jumping --variant mpc``).

Profile the graph's processes with py-spy, e.g. ``py-spy record -o sim.svg --pid
PID`` on the simulator while ``splitter launch lunar_jumping`` runs.
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import tempfile
import time
from pathlib import Path

from splitter_bringup.analysis.summary import metric_values

GOAL_REAL_TIME_FACTOR = 5.0  # [-] issue 18: lockstep graph flight at >= 5x real time
# issue 30: lunar_jumping's flight per graph mode, and the CPU of all its processes
GOAL_MODE_REAL_TIME_FACTOR = {"processes": 2.5, "in-process": 3.5}  # [-]
GOAL_LIBRARY_REAL_TIME_FACTOR = 10.0  # [-]
GOAL_CPU_PER_SIMULATED_S = 0.8  # [CPU s / simulated s]
GOAL_CPU_STARTUP_S = 5.0  # [CPU s] allowed on top for start-up
DEFAULT_SCENARIOS = ("lunar_jumping", "spin_stabilization")
GRAPH_MODES = ("processes", "in-process")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``splitter bench graph``."""
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--scenario",
        action="append",
        default=None,
        help=f"scenario to run (repeatable; default: {', '.join(DEFAULT_SCENARIOS)})",
    )
    parser.add_argument("--variant", default="mpc", help="variant to run (default: mpc)")
    parser.add_argument(
        "--mode",
        action="append",
        choices=GRAPH_MODES,
        default=None,
        help=f"graph mode (repeatable; default: {', '.join(GRAPH_MODES)})",
    )
    parser.add_argument("--out", type=Path, default=None, help="keep the runs in this folder")
    parser.add_argument(
        "--plot",
        type=Path,
        default=None,
        metavar="PNG",
        help="also plot where each flight's wall time goes (floor, library loop, the rest)",
    )


def cpu_seconds() -> float:
    """User + system CPU [s] of this process and of the children it has waited for.

    A node's solver worker is its child: waited for by the node, its CPU reaches the
    node's children account, and the node's reaches ours when the launcher waits.
    """
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def cpu_goal_s(duration_s: float) -> float:
    """Issue 30's CPU budget [s] of a graph run of ``duration_s`` simulated seconds."""
    return GOAL_CPU_PER_SIMULATED_S * duration_s + GOAL_CPU_STARTUP_S


METRIC_FLOOR = 1e-3  # figures smaller than this (in their unit) are compared absolutely


def largest_relative_difference(a: dict[str, float], b: dict[str, float]) -> tuple[float, str]:
    """(largest |a - b| / max(|a|, |b|, METRIC_FLOOR) over the shared metrics, its name).

    The floor keeps figures that are zero up to round-off (a residual of 1e-7 rad/s in
    one backend, 1e-9 in the other) from counting as 100 % apart.
    """
    worst = (0.0, "")
    for key in sorted(set(a) & set(b)):
        diff = abs(a[key] - b[key])
        if diff > 0.0:
            worst = max(worst, (diff / max(abs(a[key]), abs(b[key]), METRIC_FLOOR), key))
    return worst


def bench_scenario(name: str, variant: str, out: Path, mode: str = "processes") -> dict:
    """Figures of one scenario variant through the graph (in ``mode``) and the library."""
    from splitter_bringup.run.graph_run import WallTiming, run_graph
    from splitter_bringup.run.library import (
        CONTROL_PERIOD_NS,
        controller_config,
        run_closed_loop,
    )
    from splitter_bringup.scenario.definition import load_scenario
    from splitter_model.model import RobotModel
    from splitter_mpc.core.controller import MorphingController
    from splitter_tools.transport_floor import graph_subscriptions, measure_transport_floor

    scenario = load_scenario(name, variant)
    timing: list[WallTiming] = []
    started, cpu_started = time.monotonic(), cpu_seconds()
    graph = run_graph(
        name, variant, out / mode / name, timing=timing, in_process=mode == "in-process"
    )
    graph_wall = time.monotonic() - started
    graph_cpu = cpu_seconds() - cpu_started
    started = time.monotonic()
    library = run_closed_loop(scenario)
    library_wall = time.monotonic() - started
    model = RobotModel()
    with MorphingController(model, controller_config(scenario)) as controller:
        started = time.monotonic()
        run_closed_loop(scenario, model=model, controller=controller)
        library_flight = time.monotonic() - started
    floor = measure_transport_floor(
        scenario.duration_s,
        scenario.sim_dt_s,
        CONTROL_PERIOD_NS * 1e-9,
        subscriptions=graph_subscriptions(
            scenario.controller.attitude_reference == "momentum_aligned"
        ),
    )
    worst, metric = largest_relative_difference(
        metric_values(graph, scenario), metric_values(library, scenario)
    )
    flight = timing[0].flight_wall_time_s
    return {
        "scenario": name,
        "variant": variant,
        "mode": mode,
        "duration_s": scenario.duration_s,
        "flight_wall_time_s": flight,
        "startup_s": timing[0].startup_s,
        "run_wall_time_s": graph_wall,
        "real_time_factor": scenario.duration_s / flight,
        "goal_real_time_factor": GOAL_MODE_REAL_TIME_FACTOR.get(mode, GOAL_REAL_TIME_FACTOR),
        "cpu_s": graph_cpu,
        "cpu_per_simulated_s": graph_cpu / scenario.duration_s,
        "goal_cpu_s": cpu_goal_s(scenario.duration_s),
        "library_wall_time_s": library_wall,
        "library_real_time_factor": scenario.duration_s / library_wall,
        "library_flight_real_time_factor": scenario.duration_s / library_flight,
        "goal_library_real_time_factor": GOAL_LIBRARY_REAL_TIME_FACTOR,
        "library_flight_wall_time_s": library_flight,
        "transport_floor_s": floor.wall_s,
        "transport_floor_messages": {"published": floor.published, "delivered": floor.delivered},
        "ceiling_real_time_factor": scenario.duration_s / (floor.wall_s + library_flight),
        "largest_metric_difference": worst,
        "largest_metric_difference_name": metric,
    }


def main(args: argparse.Namespace) -> int:
    """Run the benchmark; prints figures, 0 when every run finished."""
    scenarios = tuple(args.scenario or DEFAULT_SCENARIOS)
    results = []
    with tempfile.TemporaryDirectory(prefix="splitter-bench-graph-") as tmp:
        out = args.out or Path(tmp)
        for name in scenarios:
            for mode in args.mode or GRAPH_MODES:
                print(f"bench graph: {name} ({mode}) ...", file=sys.stderr, flush=True)
                results.append(bench_scenario(name, args.variant, out, mode))
    if args.plot is not None:
        from splitter_bringup.figures.plots import plot_graph_time

        plot_graph_time(
            results,
            args.plot,
            GOAL_REAL_TIME_FACTOR,
            "Lockstep graph: where a flight's wall time goes (splitter bench graph)",
        )
        print(f"wrote {args.plot}", file=sys.stderr)
    if args.json:
        print(json.dumps({"goal_real_time_factor": GOAL_REAL_TIME_FACTOR, "runs": results}))
        return 0
    for r in results:
        print(
            f"{r['scenario']}/{r['variant']} ({r['mode']}): graph flight "
            f"{r['flight_wall_time_s']:.1f} s wall for {r['duration_s']:.0f} s = "
            f"{r['real_time_factor']:.1f}x real time (goal >= "
            f"{r['goal_real_time_factor']:g}x), start-up {r['startup_s']:.1f} s; library "
            f"flight {r['library_flight_real_time_factor']:.1f}x (goal >= "
            f"{r['goal_library_real_time_factor']:g}x); largest metric difference "
            f"{100 * r['largest_metric_difference']:.3g} % ({r['largest_metric_difference_name']})"
        )
        print(
            f"  CPU of all its processes: {r['cpu_s']:.1f} s = "
            f"{r['cpu_per_simulated_s']:.2f} per simulated second (goal <= "
            f"{GOAL_CPU_PER_SIMULATED_S:g} per s + {GOAL_CPU_STARTUP_S:g} s = "
            f"{r['goal_cpu_s']:.1f} s)"
        )
        print(
            f"  bound in one process: transport floor {r['transport_floor_s']:.2f} s + "
            f"library flight {r['library_flight_wall_time_s']:.2f} s = "
            f"{r['ceiling_real_time_factor']:.1f}x real time at best"
        )
    return 0
