"""``splitter replay BAG``: re-run the MPC on a recorded run's inputs, compare its setpoints.

Exit code 0 when every setpoint is reproduced within the tolerance or differs
for an accounted cause (a wall-time failure of a solve and its consequences:
:mod:`splitter_bringup.analysis.replay_accounting`), 1 when a difference is
unexplained, 2 when the bag cannot be replayed (no parameters, no inputs, the
MPC did not answer).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import rclpy

from splitter_msgs_py.environment import apply_ros_environment

DEFAULT_TOLERANCE_KG_M2 = 1e-9  # [kg m^2] (splitter_bringup.run.replay's default)
SHOWN_DIFFERENCES = 10  # unexplained ticks listed in the text output


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``splitter replay``."""
    parser.add_argument("bag", type=Path, help="bag folder of a `splitter run` / `launch`")
    parser.add_argument(
        "--tolerance",
        type=float,
        default=DEFAULT_TOLERANCE_KG_M2,
        help="largest difference of an inertia setpoint component, recorded vs replayed, for "
        "a tick to count as reproduced [kg m^2] (default %(default)g); a tick above it must "
        "have an accounted cause (exit code 1 otherwise)",
    )
    parser.add_argument(
        "--params",
        type=Path,
        help="the MPC's ROS 2 parameter file (default: the one the bag carries, else the "
        "run folder's params/inertial_morphing_mpc.yaml)",
    )
    parser.add_argument("--end", type=float, help="stop at this simulated time [s]")
    parser.add_argument("--json", action="store_true", help="print figures as JSON")


def main(args: argparse.Namespace) -> int:
    """Replay, print the comparison and the cause of every difference."""
    from splitter_bringup.run.replay import ReplayError, replay_mpc

    # A private domain (215-232 are safe on Linux): the replay must not talk to a graph
    # that may be running.
    apply_ros_environment(domain_id=int(os.environ.get("SPLITTER_REPLAY_DOMAIN_ID", "215")))
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        result = replay_mpc(args.bag, context, end_s=args.end, params_file=args.params)
    except ReplayError as exc:
        print(f"splitter replay: {exc}", file=sys.stderr)
        return 2
    finally:
        context.try_shutdown()
    acc = result.account(args.tolerance)
    figures = {
        "parameters": result.parameters_source,
        "ticks": acc.ticks,
        "identical": acc.identical,
        "within_tolerance": acc.within_tolerance,
        "tolerance_kg_m2": acc.tolerance_kg_m2,
        "max_abs_diff_kg_m2": acc.max_abs_diff_kg_m2,
        "skipped_ticks": acc.skipped_ticks,
        "parameters_changed_live_at_s": (
            None if result.parameters_changed_ns is None else result.parameters_changed_ns * 1e-9
        ),
        "recorded_timing_failures_s": [t * 1e-9 for t in acc.recorded_timing_failures],
        "replayed_timing_failures_s": [t * 1e-9 for t in acc.replayed_timing_failures],
        "differences_by_cause": {
            cause: {"ticks": n, "max_abs_diff_kg_m2": d} for cause, (n, d) in acc.by_cause().items()
        },
        "unexplained": [
            {"t_s": d.t_ns * 1e-9, "diff_kg_m2": d.diff_kg_m2, "detail": d.detail}
            for d in acc.unexplained
        ],
        "accounted_for": acc.accounted_for,
    }
    if args.json:
        print(json.dumps(figures, indent=2))
    else:
        _print_text(acc, result.parameters_source)
        if result.parameters_changed_ns is not None:
            print(
                f"the recorded MPC's parameters were changed live by "
                f"{result.parameters_changed_ns * 1e-9:.3f} s (the bag carries its start-up ones)"
            )
    return 0 if acc.accounted_for else 1


def _print_text(acc, source: str) -> None:
    print(f"MPC parameters: {source}")
    print(
        f"{acc.ticks} setpoints replayed: {acc.identical} identical, {acc.within_tolerance} "
        f"within {acc.tolerance_kg_m2:g} kg m^2 (largest component difference "
        f"{acc.max_abs_diff_kg_m2:.3g} kg m^2)"
    )
    if acc.skipped_ticks:
        print(f"{acc.skipped_ticks} control ticks the recorded MPC did not answer (not replayed)")
    if acc.recorded_timing_failures:
        times = ", ".join(f"{t * 1e-9:.2f}" for t in acc.recorded_timing_failures)
        print(f"recorded solves failed for wall time at t = {times} s")
    if acc.replayed_timing_failures:
        times = ", ".join(f"{t * 1e-9:.2f}" for t in acc.replayed_timing_failures)
        print(f"replayed solves failed for wall time at t = {times} s")
    for cause, (n, d) in acc.by_cause().items():
        print(f"  {cause}: {n} ticks, up to {d:.3g} kg m^2")
    for d in acc.unexplained[:SHOWN_DIFFERENCES]:
        print(f"  unexplained t = {d.t_ns * 1e-9:.3f} s: {d.diff_kg_m2:.3g} kg m^2 ({d.detail})")
    print(
        "every difference accounted for"
        if acc.accounted_for
        else f"{len(acc.unexplained)} differing ticks unexplained"
    )
