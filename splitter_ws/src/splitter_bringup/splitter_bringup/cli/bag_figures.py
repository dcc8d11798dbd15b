"""The arguments shared by the verbs that draw a recorded bag (``splitter plot``, ``animate``)."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_bag_figure_arguments(parser: argparse.ArgumentParser, out_help: str) -> None:
    """``BAG``, ``--out`` (described by ``out_help``), ``--gravity`` and ``--title``."""
    parser.add_argument("bag", type=Path, help="bag directory (metadata.yaml + .mcap)")
    parser.add_argument("--out", type=Path, required=True, help=out_help)
    parser.add_argument(
        "--gravity",
        type=float,
        default=None,
        help="gravity [m/s^2] (default: the bag's custom_data, else 0)",
    )
    parser.add_argument("--title", default="", help="figure title (default: the bag's name)")
