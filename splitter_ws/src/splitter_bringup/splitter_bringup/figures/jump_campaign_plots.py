"""Figures of a jumping campaign (PNG, matplotlib Agg).

Plotting only: the numbers come from :mod:`splitter_bringup.analysis.jump_campaign`.

* :func:`plot_success_by_factor`: each variant's success rate against every randomized
  factor of the draws (binned), one panel per factor;
* :func:`plot_failure_modes`: each variant's outcome counts side by side.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from splitter_bringup.analysis.jump_campaign import (
    OUTCOMES,
    JumpDrawResult,
    binned_success,
)
from splitter_bringup.figures.plots import save_figure

_VARIANT_STYLE = {"mpc": ("tab:blue", "o"), "open_loop": ("tab:orange", "s")}


def plot_success_by_factor(
    results: Sequence[JumpDrawResult],
    variants: Sequence[str],
    path: Path,
    title: str = "",
    *,
    bins: int = 5,
) -> Path:
    """Success rate of each variant against each randomized factor, binned."""
    factors = list(results[0].draw.factors()) if results else []
    cols = 3
    rows = max(1, -(-len(factors) // cols))
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.2 * rows), squeeze=False)
    for ax, factor in zip(axes.ravel(), factors, strict=False):
        for variant in variants:
            colour, marker = _VARIANT_STYLE.get(variant, ("tab:gray", "^"))
            centres, rate, counts = binned_success(results, variant, factor, bins)
            shown = counts > 0
            ax.plot(centres[shown], rate[shown], marker=marker, color=colour, label=variant)
        ax.set_title(factor, fontsize=9)
        ax.set_ylim(-0.05, 1.05)
        ax.grid(alpha=0.3)
    for ax in axes.ravel()[len(factors) :]:
        ax.axis("off")
    axes[0][0].set_ylabel("success rate")
    axes[0][0].legend(fontsize=8)
    return save_figure(fig, path, title or "success against each randomized factor")


def plot_failure_modes(
    results: Sequence[JumpDrawResult], variants: Sequence[str], path: Path, title: str = ""
) -> Path:
    """Outcome counts per variant (bars side by side)."""
    fig, ax = plt.subplots(figsize=(9, 4))
    x = np.arange(len(OUTCOMES))
    width = 0.8 / max(1, len(variants))
    for k, variant in enumerate(variants):
        colour, _ = _VARIANT_STYLE.get(variant, ("tab:gray", "^"))
        counts = [
            sum(r.outcomes[variant].outcome == o for r in results if variant in r.outcomes)
            for o in OUTCOMES
        ]
        ax.bar(
            x + (k - (len(variants) - 1) / 2) * width, counts, width, color=colour, label=variant
        )
    ax.set_xticks(x, OUTCOMES, rotation=20)
    ax.set_ylabel("draws")
    ax.legend()
    ax.grid(axis="y", alpha=0.3)
    return save_figure(fig, path, title or "outcomes")
