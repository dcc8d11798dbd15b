"""``splitter animate BAG --out FILE.mp4|.gif``: the recorded flight in 3D.

The bag is read into a :class:`RunSeries` (:mod:`splitter_bringup.analysis.bag_series`)
plus the two hemis' contact forces and the ground its simulator flew over; the
frames come from :mod:`splitter_bringup.analysis.flight_frames`, the drawing and
encoding from :mod:`splitter_bringup.figures.animation`. ``splitter run`` writes one
per variant with :func:`splitter_bringup.figures.flight_animation.write_animation`.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys

from splitter_bringup.analysis.flight_frames import DEFAULT_FPS
from splitter_bringup.cli.bag_figures import add_bag_figure_arguments, read_bag_figure_input
from splitter_bringup.figures.flight_animation import write_animation

_log = logging.getLogger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``splitter animate``."""
    add_bag_figure_arguments(parser, "FILE.mp4 or FILE.gif")
    parser.add_argument("--fps", type=float, default=DEFAULT_FPS, help="frames per second")
    parser.add_argument("--width", type=int, default=480, help="[px] (even)")
    parser.add_argument("--height", type=int, default=360, help="[px] (even)")


def main(args: argparse.Namespace) -> int:
    """Read the bag, render, print what was written; 1 on an unreadable bag, 2 on bad options."""
    from splitter_bringup.figures.animation import FORMATS

    if args.out.suffix.lower() not in FORMATS:
        print(f"splitter animate: --out must end in {' or '.join(FORMATS)}", file=sys.stderr)
        return 2
    if not args.fps > 0.0 or args.width < 16 or args.height < 16:
        print("splitter animate: --fps must be > 0 and the size >= 16 px", file=sys.stderr)
        return 2
    bag = read_bag_figure_input(args, "animate", contact_forces=True)
    if bag is None:
        return 1
    series, contact = bag.series, bag.contact_forces_n
    size = (args.width // 2 * 2, args.height // 2 * 2)
    info = write_animation(
        series,
        args.out,
        bag.title,
        fps=args.fps,
        size_px=size,
        contact_forces_n=contact,
        terrain=bag.terrain,
    )
    print(
        json.dumps(
            {
                "animation": str(info.path),
                "frames": info.frames,
                "fps": info.fps,
                "duration_s": info.duration_s,
                "bag_duration_s": float(series.t_s[-1] - series.t_s[0]),
            },
            indent=2,
        )
    )
    return 0
