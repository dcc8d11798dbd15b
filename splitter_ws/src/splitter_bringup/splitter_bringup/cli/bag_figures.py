"""What the verbs that draw a recorded bag share (``splitter plot``, ``animate``).

Their arguments (:func:`add_bag_figure_arguments`) and the reading of the bag
(:func:`read_bag_figure_input`), with the ground its simulator flew over
(:func:`bag_terrain`: the simulator's ``ground_*`` parameters the bag carries).
"""

from __future__ import annotations

import argparse
import logging
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from splitter_model.terrain import FLAT, Terrain

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from splitter_bringup.analysis.series import RunSeries

_log = logging.getLogger(__name__)
SIMULATOR_NODE = "simulator"  # the graph's simulator node (its parameters in the bag)


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


@dataclass(frozen=True)
class BagFigureInput:
    """What a verb draws: the bag's series, its title and (when asked) the contact forces."""

    series: RunSeries
    title: str
    contact_forces_n: NDArray[np.float64] | None = None  # (n, 2, 3) [N], None: not recorded
    terrain: Terrain = FLAT  # the ground of the run (level when the bag does not say)


def bag_terrain(bag_dir: Path) -> Terrain:
    """The ground the bag's simulator flew over, from its ``ground_*`` parameters (the
    bag's attachment ``params/simulator.yaml``, else the run folder's
    ``params/simulator.yaml`` beside the bag). Level when neither says, or (with a
    warning) when they cannot be read."""
    from splitter_bag.core.metadata import MetadataError
    from splitter_bag.core.node_parameters import (
        ParameterFileError,
        bag_node_parameters,
        read_parameter_file,
    )

    try:
        params = bag_node_parameters(bag_dir).get(SIMULATOR_NODE)
        beside = Path(bag_dir).parent / "params" / f"{SIMULATOR_NODE}.yaml"
        if params is None and beside.is_file():
            _, params = read_parameter_file(beside)
        if params is None:
            return FLAT
        return Terrain.from_parameters(
            params.get("ground_slope_deg", 0.0),
            params.get("ground_slope_azimuth_deg", 0.0),
            params.get("ground_steps_m", ()),
        )
    except (ParameterFileError, MetadataError, OSError, ValueError, TypeError) as exc:
        _log.warning("%s: the ground is drawn level (its parameters: %s)", bag_dir, exc)
        return FLAT


def read_bag_figure_input(
    args: argparse.Namespace, verb: str, *, contact_forces: bool = False
) -> BagFigureInput | None:
    """``args.bag`` read for ``splitter <verb>``; None (the reason printed) if unreadable."""
    from splitter_bag.core.metadata import MetadataError
    from splitter_bringup.analysis.bag_series import BagSeriesError
    from splitter_bringup.run.run_bag import contact_forces_from_bag, read_run_series

    try:
        series = read_run_series(args.bag, gravity_m_s2=args.gravity)
        contact = contact_forces_from_bag(args.bag, series.t_s) if contact_forces else None
    except (BagSeriesError, MetadataError, FileNotFoundError) as exc:
        print(f"splitter {verb}: {exc}", file=sys.stderr)
        return None
    title = args.title or args.bag.resolve().name
    return BagFigureInput(series, title, contact, bag_terrain(args.bag))
