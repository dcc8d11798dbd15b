"""Figures of the actuator sizing and of a run check (matplotlib, Agg). No math here."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from numpy.typing import ArrayLike

from splitter_bringup.analysis.actuator_sizing import SizingReport
from splitter_bringup.analysis.run_check import LimitCheck
from splitter_bringup.figures.plots import save_figure

FIGURE_DPI = 120  # [dots per inch]


def plot_sizing(report: SizingReport, path: Path) -> Path:
    """Ours beside the paper's (relative error) and requirement against capability."""
    rows = [f for f in report.figures if f.paper is not None]
    fig, (ax_err, ax_cap) = plt.subplots(1, 2, figsize=(12, 4.5))
    errors = [100.0 * (f.relative_error or 0.0) for f in rows]
    colors = ["tab:green" if f.within_tolerance else "tab:red" for f in rows]
    ax_err.barh([f.label for f in rows], errors, color=colors)
    for limit in (-3.0, 3.0):
        ax_err.axvline(limit, color="k", linestyle="--", linewidth=0.8)
    ax_err.set_xlabel("relative error to the paper [%]")
    ax_err.set_title("reproduced figures (dashed: 3 %)")
    ax_err.invert_yaxis()
    need = [report.figure("hip_torque_nm").value, report.figure("hip_speed_rpm").value]
    have = [report.figure("peak_torque_nm").value, report.figure("output_speed_rpm").value]
    cont = report.figure("continuous_torque_nm").value
    x = np.arange(2)
    ax_cap.bar(x, np.array(need) / np.array(have), 0.5, label="jump requirement")
    ax_cap.hlines(cont / have[0], -0.35, 0.35, colors="tab:orange", linestyles="--",
                  label="continuous torque")  # fmt: skip
    ax_cap.axhline(1.0, color="k", linewidth=0.8, label="peak torque / max speed")
    ax_cap.set_xticks(x, ["hip torque", "hip speed"])
    ax_cap.set_ylim(0.0, 1.1)
    ax_cap.set_ylabel("fraction of the geared motor's peak [-]")
    ax_cap.set_title("TBM2G-07613A, 10:1")
    ax_cap.legend()
    return save_figure(fig, path, None, dpi=FIGURE_DPI)


def plot_run_check(
    t_s: ArrayLike,
    limb_speed_rad_s: ArrayLike,
    tether_speed_m_s: ArrayLike,
    checks: Sequence[LimitCheck],
    path: Path,
) -> Path:
    """Worst limb joint speed and tether speed over time against their limits."""
    limits = {c.key: c.limit for c in checks}
    fig, (ax_j, ax_t) = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    ax_j.plot(t_s, np.max(np.abs(np.asarray(limb_speed_rad_s)), axis=1), label="worst limb joint")
    ax_j.axhline(limits["limb_joint_speed"], color="r", linestyle="--", label="800 RPM limit")
    ax_j.set_ylabel("joint speed [rad/s]")
    ax_j.legend()
    ax_t.plot(t_s, np.abs(np.asarray(tether_speed_m_s)), label="tether")
    ax_t.axhline(limits["tether_speed"], color="r", linestyle="--", label="reel limit")
    ax_t.set_ylabel("tether speed [m/s]")
    ax_t.set_xlabel("t [s]")
    ax_t.legend()
    return save_figure(fig, path, None, dpi=FIGURE_DPI)
