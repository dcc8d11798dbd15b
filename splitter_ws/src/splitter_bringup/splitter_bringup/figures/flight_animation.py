"""A run's flight drawn in 3D to an mp4 or gif: its frames, then the drawing and encoding.

The frames come from :mod:`splitter_bringup.analysis.flight_frames`, the drawing and
encoding from :mod:`splitter_bringup.figures.animation`. ROS-free.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from splitter_bringup.analysis.flight_frames import DEFAULT_FPS
from splitter_bringup.analysis.series import RunSeries
from splitter_model.terrain import FLAT, Terrain


def write_animation(
    series: RunSeries,
    path: Path,
    title: str = "",
    *,
    fps: float = DEFAULT_FPS,
    size_px: tuple[int, int] = (480, 360),
    contact_forces_n: NDArray[np.float64] | None = None,
    terrain: Terrain = FLAT,
):
    """Frames of ``series`` over ``terrain`` drawn to ``path``; returns the ``AnimationInfo``."""
    from splitter_bringup.analysis.flight_frames import flight_frames
    from splitter_bringup.figures.animation import render_animation

    frames = flight_frames(series, fps, contact_forces_n, terrain=terrain)
    return render_animation(frames, path, title, size_px)
