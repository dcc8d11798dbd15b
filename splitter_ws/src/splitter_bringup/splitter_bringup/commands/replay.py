"""``splitter replay BAG``: re-run the MPC on a recorded run's inputs, compare its setpoints."""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import rclpy

from splitter_msgs_py.environment import apply_ros_environment


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``splitter replay``."""
    parser.add_argument("bag", type=Path, help="bag folder of a `splitter run` / `launch`")
    parser.add_argument(
        "--tolerance",
        type=float,
        default=1e-6,
        help="largest setpoint difference accepted [kg m^2] (exit code 1 above it)",
    )
    parser.add_argument("--end", type=float, help="stop at this simulated time [s]")
    parser.add_argument("--json", action="store_true", help="print figures as JSON")


def main(args: argparse.Namespace) -> int:
    """Replay, print the comparison, exit 1 when it exceeds the tolerance."""
    from splitter_bringup.replay import replay_mpc

    # A private domain (215-232 are safe on Linux): the replay must not talk to a graph
    # that may be running.
    apply_ros_environment(domain_id=int(os.environ.get("SPLITTER_REPLAY_DOMAIN_ID", "215")))
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        result = replay_mpc(args.bag, context, end_s=args.end)
    finally:
        context.try_shutdown()
    figures = {
        "ticks": len(result.stamps_ns),
        "max_abs_diff_kg_m2": result.max_abs_diff_kg_m2,
        "tolerance_kg_m2": args.tolerance,
        "reproduced": result.max_abs_diff_kg_m2 <= args.tolerance,
    }
    if args.json:
        print(json.dumps(figures, indent=2))
    else:
        print(
            f"{figures['ticks']} setpoints replayed; largest difference "
            f"{figures['max_abs_diff_kg_m2']:.3g} kg m^2 (tolerance {args.tolerance:g})"
        )
    return 0 if figures["reproduced"] else 1
