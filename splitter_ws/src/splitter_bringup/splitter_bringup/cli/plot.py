"""``splitter plot BAG --out PNGDIR``: the paper's figures from a recorded bag.

The bag is read into a :class:`RunSeries` (:mod:`splitter_bringup.analysis.bag_series`);
the flight figure (angular velocity, radii, inertia against its setpoint, Euler
angles) and the quaternion map come from :mod:`splitter_bringup.figures.plots`, the
same code ``splitter run`` uses. The trajectory and velocity figure (paper
Fig. 12, lunar jumping) is drawn here, from the series' own arrays.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from splitter_bringup.cli.bag_figures import add_bag_figure_arguments, read_bag_figure_input
from splitter_bringup.figures.trajectory import plot_trajectory, trajectory_summary


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_bag_figure_arguments(parser, "directory for the PNG files")
    parser.add_argument("--npz", action="store_true", help="also save the series as .npz")


def main(args: argparse.Namespace) -> int:
    from splitter_bringup.figures.plots import plot_flight, plot_quaternion_map

    bag = read_bag_figure_input(args, "plot")
    if bag is None:
        return 1
    series, title = bag.series, bag.title
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    written = [
        plot_flight(series, out / "flight.png", title),
        plot_quaternion_map(series, out / "quaternion.png", title),
        plot_trajectory(series, out / "trajectory.png", title, terrain=bag.terrain),
    ]
    if args.npz:
        series.save_npz(out / "series.npz")
    w_end = series.angular_velocity_rad_s[-1]
    summary = {
        "samples": len(series),
        "final_angular_velocity_rad_s": [float(x) for x in w_end],
        **trajectory_summary(series),
        "figures": [str(p) for p in written],
    }
    print(json.dumps(summary, indent=2))
    return 0
