"""``splitter animate BAG --out FILE.mp4|.gif``: the recorded flight in 3D.

The bag is read into a :class:`RunSeries` (:mod:`splitter_bringup.core.bag_series`)
plus the two hemis' contact forces; the frames come from
:mod:`splitter_bringup.core.flight_frames`, the drawing and encoding from
:mod:`splitter_bringup.core.animation`. ``splitter run`` writes one per variant
with :func:`write_animation`.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from splitter_bringup.core.flight_frames import DEFAULT_FPS
from splitter_bringup.core.series import RunSeries

_log = logging.getLogger(__name__)
_NS_PER_S = 1_000_000_000


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``splitter animate``."""
    parser.add_argument("bag", type=Path, help="bag directory (metadata.yaml + .mcap)")
    parser.add_argument("--out", type=Path, required=True, help="FILE.mp4 or FILE.gif")
    parser.add_argument("--fps", type=float, default=DEFAULT_FPS, help="frames per second")
    parser.add_argument("--width", type=int, default=480, help="[px] (even)")
    parser.add_argument("--height", type=int, default=360, help="[px] (even)")
    parser.add_argument(
        "--gravity",
        type=float,
        default=None,
        help="gravity [m/s^2] (default: the bag's custom_data, else 0)",
    )
    parser.add_argument("--title", default="", help="figure title (default: the bag's name)")


def contact_forces_from_bag(bag_dir: Path, t_s: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """(n, 2, 3) contact force of each hemi [N] at the series times, or None if not recorded."""
    from rclpy.serialization import deserialize_message

    from splitter_bag.core.reader import read_messages
    from splitter_bringup.core.bag_series import forward_fill
    from splitter_msgs_py import names
    from splitter_msgs_py.conversions import TOPIC_MESSAGE_CLASSES, wrench_from_msg

    stamps: dict[str, list[int]] = {t: [] for t in names.CONTACT_WRENCHES}
    forces: dict[str, list[NDArray[np.float64]]] = {t: [] for t in names.CONTACT_WRENCHES}
    for m in read_messages(bag_dir, topics=list(names.CONTACT_WRENCHES)):
        sample = wrench_from_msg(deserialize_message(m.data, TOPIC_MESSAGE_CLASSES[m.topic]))
        stamps[m.topic].append(sample.t_ns)
        forces[m.topic].append(np.asarray(sample.force_n, dtype=float))
    if not all(stamps.values()):
        _log.info("%s: no contact wrenches recorded, no contact arrows", bag_dir)
        return None
    grid = np.round(np.asarray(t_s) * _NS_PER_S).astype(np.int64)
    return np.stack(
        [
            forward_fill(stamps[t], np.array(forces[t]), grid).astype(float)
            for t in names.CONTACT_WRENCHES
        ],
        axis=1,
    )


def write_animation(
    series: RunSeries,
    path: Path,
    title: str = "",
    *,
    fps: float = DEFAULT_FPS,
    size_px: tuple[int, int] = (480, 360),
    contact_forces_n: NDArray[np.float64] | None = None,
):
    """Frames of ``series`` drawn to ``path``; returns the :class:`AnimationInfo`."""
    from splitter_bringup.core.animation import render_animation
    from splitter_bringup.core.flight_frames import flight_frames

    frames = flight_frames(series, fps, contact_forces_n)
    return render_animation(frames, path, title, size_px)


def main(args: argparse.Namespace) -> int:
    """Read the bag, render, print what was written; 1 on an unreadable bag, 2 on bad options."""
    from splitter_bag.core.metadata import MetadataError
    from splitter_bringup.core.animation import FORMATS
    from splitter_bringup.core.bag_series import BagSeriesError
    from splitter_bringup.run_bag import read_run_series

    if args.out.suffix.lower() not in FORMATS:
        print(f"splitter animate: --out must end in {' or '.join(FORMATS)}", file=sys.stderr)
        return 2
    if not args.fps > 0.0 or args.width < 16 or args.height < 16:
        print("splitter animate: --fps must be > 0 and the size >= 16 px", file=sys.stderr)
        return 2
    try:
        series = read_run_series(args.bag, gravity_m_s2=args.gravity)
        contact = contact_forces_from_bag(args.bag, series.t_s)
    except (BagSeriesError, MetadataError, FileNotFoundError) as exc:
        print(f"splitter animate: {exc}", file=sys.stderr)
        return 1
    title = args.title or args.bag.resolve().name
    size = (args.width // 2 * 2, args.height // 2 * 2)
    info = write_animation(
        series, args.out, title, fps=args.fps, size_px=size, contact_forces_n=contact
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
