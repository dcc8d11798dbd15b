"""The trajectory and velocity figure of a jumping run (paper Fig. 12), from a run's series.

Over a terrain that is not level (:class:`splitter_model.terrain.Terrain`) the side
view and the height panel also show the ground under the path. PNG, matplotlib Agg;
ROS-free.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_bringup.analysis.series import RunSeries
from splitter_model.terrain import FLAT, Terrain

MIN_LABELLED_PHASE_S = 0.2  # [s] shorter gait phases get a line but no label
GROUND_COLOR = "saddlebrown"
GROUND_FILL_ALPHA = 0.15


def trajectory_summary(series: RunSeries) -> dict[str, float]:
    """Numbers printed with the trajectory figure: peak speeds and travelled distance."""
    v = series.velocity_m_s
    p = series.position_m
    return {
        "duration_s": float(series.t_s[-1] - series.t_s[0]),
        "peak_horizontal_speed_m_s": float(np.max(np.hypot(v[:, 0], v[:, 1]))),
        "peak_v_x_m_s": float(np.max(v[:, 0])),
        "peak_height_m": float(np.max(p[:, 2])),
        "horizontal_distance_m": float(np.hypot(*(p[-1, :2] - p[0, :2]))),
    }


def ground_under_path_m(terrain: Terrain, position_m: ArrayLike) -> NDArray[np.float64]:
    """(n,) the ground's height [m] under each point of the path (rows x, y, z [m])."""
    p = np.atleast_2d(np.asarray(position_m, dtype=float))
    return np.array([terrain.height_m(float(x), float(y)) for x, y in p[:, :2]])


def plot_trajectory(
    series: RunSeries, path: Path, title: str = "", terrain: Terrain = FLAT
) -> Path:
    """Centre-of-mass path (x-z and x-y) and world velocity, with the jump force if recorded.

    ``terrain`` (not level): the ground under the path in the side view (and on the
    height panel when no jump force was recorded), and the steps' footprints in the top
    view.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    from splitter_bringup.figures.plots import save_figure

    t = series.t_s
    p = series.position_m
    v = series.velocity_m_s
    ground = None if terrain.flat else ground_under_path_m(terrain, p)
    fig, axes = plt.subplots(2, 2, figsize=(12, 8))
    ax = axes[0, 0]
    ax.plot(p[:, 0], p[:, 2], label="centre of mass")
    if ground is not None:
        ax.plot(p[:, 0], ground, color=GROUND_COLOR, lw=1.0, label="ground under the path")
        ax.fill_between(
            p[:, 0],
            ground,
            min(float(ground.min()), float(p[:, 2].min())),
            color=GROUND_COLOR,
            alpha=GROUND_FILL_ALPHA,
            lw=0,
        )
        ax.legend(loc="best", fontsize=8)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    ax.set_title("trajectory (side view)")
    ax.grid(True, alpha=0.3)
    ax = axes[0, 1]
    ax.plot(p[:, 0], p[:, 1])
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("trajectory (top view)")
    for step in terrain.steps:
        ax.add_patch(
            Rectangle(
                (step.x_min_m, step.y_min_m),
                step.x_max_m - step.x_min_m,
                step.y_max_m - step.y_min_m,
                color=GROUND_COLOR,
                alpha=GROUND_FILL_ALPHA,
                lw=0,
            )
        )
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax = axes[1, 0]
    for i, name in enumerate("xyz"):
        ax.plot(t, v[:, i], label=f"$v_{name}$")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("velocity (world) [m/s]")
    ax.legend(loc="best")
    ax.grid(True, alpha=0.3)
    ax = axes[1, 1]
    if series.jump_force_n is not None:
        for i, name in enumerate("xyz"):
            ax.plot(t, series.jump_force_n[:, i], label=f"$F_{name}$")
        ax.set_ylabel("jump thrust (world) [N]")
        ax.legend(loc="best")
    else:
        ax.plot(t, p[:, 2])
        if ground is not None:
            ax.plot(t, ground, color=GROUND_COLOR, lw=1.0)
        ax.set_ylabel("height z [m]")
    if series.gait_phase:
        changes = [i for i in range(1, len(t)) if series.gait_phase[i] != series.gait_phase[i - 1]]
        for i in changes:
            ax.axvline(t[i], color="grey", alpha=0.4)
        # label the phases that last (a cartwheeling hemi taps the ground many times)
        bounds = [0, *changes, len(t)]
        for start, end in itertools.pairwise(bounds):
            if t[end - 1] - t[start] >= MIN_LABELLED_PHASE_S:
                ax.text(
                    t[start],
                    ax.get_ylim()[1],
                    series.gait_phase[start],
                    rotation=90,
                    fontsize=7,
                    va="top",
                )
    ax.set_xlabel("t [s]")
    ax.grid(True, alpha=0.3)
    return save_figure(fig, path, title)
