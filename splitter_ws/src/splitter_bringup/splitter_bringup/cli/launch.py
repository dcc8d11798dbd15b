"""``splitter launch``: start every node of a scenario as its own process (or all in one)."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from splitter_bringup.analysis.watchdog import DEFAULT_STALL_TIMEOUT_S
from splitter_bringup.run.launcher import launch
from splitter_bringup.scenario.definition import available_scenarios, load_scenario

LOG = logging.getLogger(__name__)
FOXGLOVE_PORT = 8765  # Foxglove's default WebSocket port


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``splitter launch``."""
    parser.add_argument(
        "scenario",
        nargs="?",
        default="lunar_jumping",
        help=f"scenario name ({', '.join(available_scenarios())}) or YAML path",
    )
    parser.add_argument("--variant", help="scenario variant (default: its first)")
    parser.add_argument("--out", type=Path, default=Path("runs/launch"), help="output folder")
    parser.add_argument(
        "--real-time", action="store_true", help="pace the simulator by the wall clock"
    )
    parser.add_argument("--rate", type=float, default=1.0, help="real-time rate factor")
    parser.add_argument("--no-record", action="store_true", help="do not record a bag")
    parser.add_argument(
        "--in-process",
        action="store_true",
        help="every node in this one process on one executor (no watchdog, no Foxglove)",
    )
    parser.add_argument(
        "--stall-timeout",
        type=float,
        default=DEFAULT_STALL_TIMEOUT_S,
        help="wall seconds without progress after which a node is named stalled "
        "(lockstep: the run stops and fails; real time: it is reported)",
    )
    parser.add_argument(
        "--foxglove",
        type=int,
        nargs="?",
        const=FOXGLOVE_PORT,
        default=None,
        metavar="PORT",
        help=f"serve the graph to Foxglove over WebSocket on PORT (default {FOXGLOVE_PORT})",
    )
    parser.add_argument(
        "--foxglove-host",
        default="127.0.0.1",
        help="address the Foxglove server binds (0.0.0.0 in a container with -p PORT:PORT)",
    )
    parser.add_argument(
        "--domain-id",
        type=int,
        help="ROS domain of the graph (default: ROS_DOMAIN_ID when set, else one no other "
        "graph on this machine uses; printed and written to OUT/domain_id)",
    )
    parser.add_argument(
        "--multi-host",
        action="store_true",
        help="opt in to DDS beyond 127.0.0.1 (default: loopback-only profile)",
    )


def main(args: argparse.Namespace) -> int:
    """Launch, wait for the end of the scenario or Ctrl-C, stop every node."""
    if args.rate <= 0.0:
        LOG.error("--rate must be > 0, got %s", args.rate)
        return 2
    if not args.stall_timeout > 0.0:
        LOG.error("--stall-timeout must be > 0, got %s", args.stall_timeout)
        return 2
    if args.foxglove is not None and not 0 <= args.foxglove <= 65535:
        LOG.error("--foxglove PORT must be in [0, 65535], got %s", args.foxglove)
        return 2
    scenario = load_scenario(args.scenario, args.variant)
    common = {
        "real_time": args.real_time,
        "rate_factor": args.rate,
        "record": not args.no_record,
        "multi_host": args.multi_host,
        "domain_id": args.domain_id,
    }
    if args.in_process:
        if args.foxglove is not None:
            LOG.error("--foxglove needs the nodes as processes (drop --in-process)")
            return 2
        from splitter_bringup.run.inprocess_launch import launch_in_process

        result = launch_in_process(scenario, args.out, **common)
    else:
        result = launch(
            scenario,
            args.out,
            **common,
            stall_timeout_s=args.stall_timeout,
            foxglove_port=args.foxglove,
            foxglove_host=args.foxglove_host,
        )
    for incident in result.incidents:
        LOG.error("during the run: %s", incident)
    for foreign in result.foreign_publishers:
        LOG.warning("a publisher the graph did not start: %s", foreign)
    for name, code in result.exit_codes.items():
        LOG.info("%-22s exit code %s", name, code)
    if result.bag_dir is not None:
        LOG.info("bag: %s", result.bag_dir)
        _log_timing(result.bag_dir)
    LOG.info("ROS domain: %s", result.domain_id)
    if result.outcome == "stopped":
        return 130
    return 0 if result.ok else 1


def _log_timing(bag_dir: Path) -> None:
    """The nodes' last timing report (latency, late commands, tether) from the bag."""
    from splitter_bringup.analysis.bag_series import BagSeriesError
    from splitter_bringup.run.run_bag import read_timing_report

    try:
        report = read_timing_report(bag_dir)
    except (BagSeriesError, OSError, ValueError) as exc:
        LOG.warning("no timing report from the bag: %s", exc)
        return
    for node, values in sorted(report.items()):
        LOG.info("%s: %s", node, ", ".join(f"{k} {v:.4g}" for k, v in sorted(values.items())))
