"""Figures of a Monte-Carlo campaign (PNG, matplotlib Agg).

Plotting only: every number shown comes from :mod:`.campaign` (binning, Wilson
intervals, direction angles) or from the draw results.

* :func:`plot_speed_dependence`: success rate (with its 95 % Wilson interval) and
  settling time against the initial rate ``|w0|``, binned.
* :func:`plot_direction_map`: the direction of ``w0`` in the body frame (azimuth
  from x towards y, elevation towards z) of every draw, coloured by outcome.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from splitter_bringup.analysis.campaign import (
    OUTCOMES,
    SUCCESS,
    DrawResult,
    binned_by_speed,
    direction_angles_deg,
)
from splitter_bringup.figures.plots import save_figure

# one colour and marker per outcome (success first), stable across figures
_STYLE = {
    SUCCESS: ("tab:green", "o"),
    "minor_axis_spin": ("tab:red", "x"),
    "wrong_axis": ("tab:purple", "s"),
    "tumbling": ("tab:orange", "^"),
    "slow_convergence": ("tab:olive", "v"),
    "solver_failure": ("tab:blue", "D"),
    "deadline_miss": ("tab:cyan", "P"),
    "diverged": ("black", "*"),
    "error": ("tab:gray", "X"),
}


def plot_speed_dependence(
    results: Sequence[DrawResult],
    path: Path,
    w_min_rad_s: float,
    w_max_rad_s: float,
    title: str = "",
    *,
    bins: int = 6,
) -> Path:
    """Success rate and settling time against ``|w0|`` (bins over [w_min, w_max])."""
    b = binned_by_speed(results, w_min_rad_s, w_max_rad_s, bins)
    centres, width = b.centres_rad_s, np.diff(b.edges_rad_s)
    fig, (ax_rate, ax_settle) = plt.subplots(2, 1, figsize=(8, 8), sharex=True)
    ax_rate.bar(centres, b.rate, width=0.9 * width, color="tab:green", alpha=0.35)
    filled = b.draws > 0
    ax_rate.errorbar(
        centres[filled],
        b.rate[filled],
        yerr=[b.rate[filled] - b.wilson_low[filled], b.wilson_high[filled] - b.rate[filled]],
        fmt="o",
        color="tab:green",
        capsize=4,
        label="success rate, 95 % Wilson interval",
    )
    for c, n, k in zip(centres, b.draws, b.successes, strict=True):
        ax_rate.annotate(f"{k}/{n}", (c, 1.02), ha="center", fontsize=8)
    ax_rate.set_ylim(0.0, 1.1)
    ax_rate.set_ylabel("success rate [-]")
    ax_rate.legend(loc="lower left")
    ax_rate.grid(True, alpha=0.3)
    ok = [r for r in results if r.success]
    ax_settle.scatter(
        [r.draw.w0_norm_rad_s for r in ok],
        [r.settling_time_s for r in ok],
        s=12,
        color="tab:green",
        alpha=0.6,
        label="successful draw",
    )
    ax_settle.plot(centres, b.settling_median_s, "k-o", label="median per bin")
    ax_settle.set_xlabel("|w0| [rad/s]")
    ax_settle.set_ylabel("settling time [s]")
    ax_settle.legend(loc="upper left")
    ax_settle.grid(True, alpha=0.3)
    ax_settle.set_xlim(b.edges_rad_s[0], b.edges_rad_s[-1])
    return save_figure(fig, path, title)


def plot_direction_map(results: Sequence[DrawResult], path: Path, title: str = "") -> Path:
    """Azimuth / elevation of ``w0`` in the body frame, one marker per draw by outcome."""
    azimuth, elevation = direction_angles_deg(np.array([r.draw.w0_rad_s for r in results]))
    outcomes = np.array([r.outcome for r in results])
    fig, ax = plt.subplots(figsize=(10, 5.5))
    for outcome in OUTCOMES:
        mine = outcomes == outcome
        if not mine.any():
            continue
        colour, marker = _STYLE[outcome]
        ax.scatter(
            azimuth[mine],
            elevation[mine],
            c=colour,
            marker=marker,
            s=18 if outcome == SUCCESS else 40,
            alpha=0.5 if outcome == SUCCESS else 0.9,
            label=f"{outcome} ({int(mine.sum())})",
        )
    for az, name in ((0.0, "+x"), (90.0, "+y"), (180.0, "-x"), (-90.0, "-y"), (-180.0, "-x")):
        ax.axvline(az, color="0.8", lw=0.8, zorder=0)
        ax.annotate(name, (az, 86.0), ha="center", fontsize=8, color="0.4")
    ax.set_xlim(-180.0, 180.0)
    ax.set_ylim(-90.0, 95.0)
    ax.set_xticks(np.arange(-180, 181, 45))
    ax.set_xlabel("azimuth of w0 in the body frame, from x towards y [deg]")
    ax.set_ylabel("elevation towards z [deg]")
    ax.legend(loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize=8)
    ax.grid(True, alpha=0.3)
    return save_figure(fig, path, title)
