"""Summary of a jumping run (paper section VII.B): speeds, jumps, range of motion.

ROS-free, from a :class:`RunSeries` however it was made. The paper reports a
2.83 m/s horizontal jumping flight, a higher peak v_x after the second jump than
after the first, and limb and tether motion "in a small range".
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from splitter_bringup.core.metrics import Metric
from splitter_bringup.core.scenario import JumpSpec
from splitter_bringup.core.series import RunSeries

AIRBORNE_PHASES = ("IN_FLIGHT", "LANDING")


def thrust_start_times(series: RunSeries, planned: tuple[JumpSpec, ...]) -> list[float]:
    """When each thrust began [s]: onsets of a non-zero jump force, else the plan's times."""
    if series.jump_force_n is not None:
        thrusting = np.linalg.norm(series.jump_force_n, axis=1) > 0.0
        onsets = np.flatnonzero(np.diff(thrusting.astype(int)) == 1) + 1
        starts = ([0] if thrusting[0] else []) + list(onsets)
        return [float(series.t_s[i]) for i in starts]
    return [j.time_s for j in planned]


def _airborne(series: RunSeries) -> NDArray[np.bool_]:
    if series.gait_phase:
        return np.array([p in AIRBORNE_PHASES for p in series.gait_phase])
    return np.ones(len(series), dtype=bool)


def jumping_summary(
    series: RunSeries, planned: tuple[JumpSpec, ...], paper: Mapping[str, Any]
) -> dict[str, Metric]:
    """Figures of a jumping run beside the paper's (section VII.B)."""
    t = series.t_s
    v = series.velocity_m_s
    horizontal = np.hypot(v[:, 0], v[:, 1])
    airborne = _airborne(series)
    starts = thrust_start_times(series, planned)
    out: dict[str, Metric] = {
        "horizontal_speed_mps": Metric(
            float(horizontal[airborne].max()) if airborne.any() else math.nan,
            "m/s",
            "largest horizontal speed of the centre of mass while airborne (IN_FLIGHT, LANDING)",
            paper.get("horizontal_speed_mps"),
        ),
        "mean_horizontal_speed_mps": Metric(
            float(np.hypot(*(series.position_m[-1, :2] - series.position_m[0, :2])) / t[-1]),
            "m/s",
            "horizontal distance travelled over the run's duration",
        ),
        "jumps_done": Metric(float(len(starts)), "-", "thrust phases that happened", len(planned)),
        "max_height_m": Metric(
            float(series.position_m[:, 2].max()), "m", "highest centre of mass above the ground"
        ),
    }
    for k, start in enumerate(starts):
        end = starts[k + 1] if k + 1 < len(starts) else t[-1] + 1.0
        window = (t >= start) & (t < end)
        out[f"peak_vx_after_jump_{k + 1}_mps"] = Metric(
            float(v[window, 0].max()),
            "m/s",
            f"largest v_x from jump {k + 1} (t = {start:.2f} s) to the next jump or the end",
            paper.get("peak_vx_second_jump") if k == 1 else None,
        )
    for axis, name in enumerate(("r_x", "r_y", "r_z")):
        r = series.radii_m[:, axis]
        out[f"range_{name}_m"] = Metric(
            float(r.max() - r.min()),
            "m",
            f"range of {name} over the run (min {r.min():.3f} m, max {r.max():.3f} m)",
            paper.get("range_of_motion") if axis == 0 else None,
        )
    tether = series.joint_position[:, -1]
    out["range_tether_length_m"] = Metric(
        float(tether.max() - tether.min()),
        "m",
        f"range of the tether length (min {tether.min():.3f} m, max {tether.max():.3f} m)",
    )
    return out
