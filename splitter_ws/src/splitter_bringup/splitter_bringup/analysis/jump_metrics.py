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

from splitter_bringup.analysis.actuator_sizing import limb_dynamic_force_limit_n
from splitter_bringup.analysis.metrics import Metric
from splitter_bringup.analysis.series import RunSeries
from splitter_bringup.scenario.definition import JumpSpec

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


STANCE_FORCE_N = 2.0  # [N] a hemi with more ground force than this is in contact (gait's threshold)
MIN_FLIGHT_S = 0.3  # [s] shorter airborne spans are bounces, not flights
REST_WINDOW_S = 1.0  # [s] the span at the end where the robot must be at rest


def phase_spans(t_s: NDArray[np.float64], phases: list[str]) -> list[tuple[str, float, float]]:
    """(phase, start [s], end [s]) of each run of equal phase labels (empty labels skipped)."""
    spans: list[tuple[str, float, float]] = []
    for i, label in enumerate(phases):
        if not label:
            continue
        if spans and spans[-1][0] == label:
            spans[-1] = (label, spans[-1][1], float(t_s[i]))
        else:
            spans.append((label, float(t_s[i]), float(t_s[i])))
    # a span lasts until the next one starts (the last one until the end of the run)
    return [
        (label, start, spans[k + 1][1] if k + 1 < len(spans) else float(t_s[-1]))
        for k, (label, start, _) in enumerate(spans)
    ]


def flight_durations(t_s: NDArray[np.float64], contact_force_n: NDArray[np.float64]) -> list[float]:
    """Durations [s] of the spans with no hemi in contact, longer than :data:`MIN_FLIGHT_S`."""
    airborne = np.all(np.linalg.norm(contact_force_n, axis=2) <= STANCE_FORCE_N, axis=1)
    edges = np.flatnonzero(np.diff(np.concatenate(([0], airborne.astype(int), [0]))))
    durations = [
        float(t_s[min(b, len(t_s) - 1)] - t_s[a])
        for a, b in zip(edges[::2], edges[1::2], strict=True)
    ]
    return [d for d in durations if d >= MIN_FLIGHT_S]


def gait_summary(series: RunSeries, planned_jumps: int) -> dict[str, Metric]:
    """Gait figures (issue: launch to rest): phases, flights, touchdown forces, rest."""
    t = series.t_s
    out: dict[str, Metric] = {}
    spans = phase_spans(t, series.gait_phase)
    if spans:
        landed = [start for label, start, _ in spans if label == "LANDED"]
        held = [end - start for label, start, end in spans[:-1] if label != "JUMP"]
        out["landed_at_s"] = Metric(
            landed[0] if landed else math.nan, "s", "first time the gait phase is LANDED"
        )
        out["phase_changes"] = Metric(
            float(len(spans) - 1),
            "-",
            f"gait phase changes (at most 2 x jumps + 4 = {2 * planned_jumps + 4}): "
            + " > ".join(label for label, *_ in spans),
        )
        out["shortest_phase_s"] = Metric(
            min(held) if held else math.nan,
            "s",
            "shortest time a phase other than JUMP was held (the last one excluded)",
        )
        out["final_phase"] = Metric(
            float(spans[-1][0] == "LANDED"), "-", "1 if the run ends LANDED"
        )
    end = t >= t[-1] - REST_WINDOW_S
    out["rest_speed_max_mps"] = Metric(
        float(np.linalg.norm(series.velocity_m_s[end], axis=1).max()),
        "m/s",
        f"largest centre-of-mass speed over the last {REST_WINDOW_S:g} s (LANDED: < 0.05)",
    )
    out["rest_angular_speed_max_rad_s"] = Metric(
        float(np.linalg.norm(series.angular_velocity_rad_s[end], axis=1).max()),
        "rad/s",
        f"largest |w| over the last {REST_WINDOW_S:g} s (LANDED: < 0.05)",
    )
    contact = series.extras.get("contact_force_n")
    if contact is None:
        return out
    contact = np.asarray(contact, dtype=float)
    limit = limb_dynamic_force_limit_n()
    force = np.linalg.norm(contact, axis=2)  # (n, 2) [N]
    landing = np.array([p in ("LANDING", "LANDED") for p in series.gait_phase], dtype=bool)
    for h, hemi in enumerate(("a", "b")):
        out[f"peak_contact_force_{hemi}_n"] = Metric(
            float(force[:, h].max()),
            "N",
            f"largest ground force on hemi {hemi} over the run (limit {limit:.0f} N)",
        )
        out[f"peak_landing_force_{hemi}_n"] = Metric(
            float(force[landing, h].max()) if landing.any() else math.nan,
            "N",
            f"largest ground force on hemi {hemi} from LANDING on (limit {limit:.0f} N)",
        )
    out["limb_force_limit_n"] = Metric(
        limit, "N", "limbs' dynamic limit: the paper's 20 kg dynamic payload x 9.81 m/s^2"
    )
    for k, duration in enumerate(flight_durations(t, contact)):
        out[f"flight_{k + 1}_s"] = Metric(duration, "s", f"duration of flight {k + 1}, no contact")
    return out
