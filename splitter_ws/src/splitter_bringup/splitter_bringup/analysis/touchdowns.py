"""Every touchdown of a run, as a landing controller is judged (issue: landing as a goal).

ROS-free, from a :class:`RunSeries` however it was made (library loop or bag). A
touchdown is the end of a flight (no hemi in contact for at least
``jump_metrics.MIN_FLIGHT_S``). For each one, at the first contact:

* ``tether_tilt_deg``: the tether axis (body x) from the ground plane;
* ``legs_tilt_deg``: each hemi's leg axis (its belly normal, body +z) from the
  ground normal; the hemis are one rigid body in the lumped model, so the two
  hemis' angles are the same number; the legs reach the ground within the
  simulator's workspace cone (``SimConfig.leg_cone_half_angle_deg``);
* ``stagger_s``: time between the two hemis' first contacts (NaN if one hemi did
  not touch within ``TOUCHDOWN_WINDOW_S``);
* ``impact_{a,b}_n``: the largest ground force on each hemi within
  ``TOUCHDOWN_WINDOW_S``;
* ``on_legs``: the legs faced the ground and no lumped mass went below it
  (deeper than ``BODY_CONTACT_DEPTH_M``) within ``TOUCHDOWN_WINDOW_S``;
* ``angular_speed_rad_s``: the spin the ground meets; and the largest ``|w|`` of
  the flight that ends there (a launch's spin shows in flight 1).

The whole run also reports how long any lumped mass was on the ground (a landing
on the body, which the contact model makes hard) and how long the tether (the
straight segment between the hemi bodies) lay on or in the terrain
(``tether_ground_contact_s``: over a step, a ridge). Heights, tilts and normals are
the terrain's (:class:`splitter_model.terrain.Terrain`: the distance to the ground a
mass touches, angles from the ground's normal); level ground by default.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from splitter_bringup.analysis.jump_metrics import MIN_FLIGHT_S, STANCE_FORCE_N
from splitter_bringup.analysis.metrics import Metric
from splitter_bringup.analysis.series import RunSeries
from splitter_model.model import RobotModel
from splitter_model.rotations import quaternion_to_matrix as rotation_matrix
from splitter_model.terrain import FLAT, Terrain
from splitter_sim.core.scene import SceneGeometry

TOUCHDOWN_WINDOW_S = 0.5  # [s] after the first contact: impact, stagger, body contact
# [m] a lumped mass this far below the ground touches it (the standing robot's start
# pose leaves its lowest limb tip 0.3 mm in the ground).
BODY_CONTACT_DEPTH_M = 1.0e-3


@dataclass(frozen=True)
class Touchdown:
    """One touchdown (module docstring for each figure)."""

    t_s: float  # [s] first contact
    tether_tilt_deg: float
    legs_tilt_deg: float
    stagger_s: float
    impact_n: tuple[float, float]  # [N] hemi a, hemi b
    on_legs: bool
    angular_speed_rad_s: float = math.nan  # [rad/s] |w| at the first contact
    flight_peak_angular_speed_rad_s: float = math.nan  # [rad/s] largest |w| of the flight


def _contact(series: RunSeries) -> NDArray[np.bool_] | None:
    force = series.extras.get("contact_force_n")
    if force is None:
        return None
    return np.linalg.norm(np.asarray(force, dtype=float), axis=2) > STANCE_FORCE_N  # (n, 2)


def lowest_mass_heights_m(
    series: RunSeries, model: RobotModel | None = None, terrain: Terrain = FLAT
) -> NDArray:
    """Distance [m] of the lowest lumped mass to the ground at each sample (inf far above).

    Mass positions from the recorded joint positions and pose (the scene's geometry);
    samples whose centre of mass is more than the robot's reach above the ground are
    skipped.
    """
    return ground_clearances_m(series, model, terrain)[0]


def ground_clearances_m(
    series: RunSeries, model: RobotModel | None = None, terrain: Terrain = FLAT
) -> tuple[NDArray, NDArray]:
    """Per sample: the lowest lumped mass's distance to the ground [m] and the tether's
    (the segment between the hemi bodies; :meth:`Terrain.segment_clearance_m`), both
    inf while the robot is far above the ground."""
    geometry = SceneGeometry(model)
    reach = math.hypot(geometry.model.radius_x_max_m, geometry.model.limb_radius_max_m)
    lowest = np.full(len(series), np.inf)
    tether = np.full(len(series), np.inf)
    position = series.position_m
    under = terrain.heights_m(position[:, :2]) if len(series) else np.zeros(0)
    slack = reach * math.tan(math.radians(terrain.slope_deg)) + max(
        (s.height_m for s in terrain.steps), default=0.0
    )
    for i in np.flatnonzero(position[:, 2] - under <= reach + 0.5 + slack):
        world = geometry.world_positions(
            position[i], series.orientation_wxyz[i], series.joint_position[i]
        )
        if terrain.flat:
            lowest[i] = float(world[:, 2].min())
            tether[i] = float(min(world[0, 2], world[5, 2]))
        else:
            lowest[i] = float(terrain.signed_distance_m(world).min())
            tether[i] = terrain.segment_clearance_m(world[0], world[5])
    return lowest, tether


def touchdowns(
    series: RunSeries,
    cone_half_angle_deg: float,
    model: RobotModel | None = None,
    lowest_m: NDArray | None = None,
    terrain: Terrain = FLAT,
) -> list[Touchdown]:
    """Every touchdown of ``series`` (module docstring); ``lowest_m``: the series'
    :func:`lowest_mass_heights_m` when already computed."""
    contact = _contact(series)
    if contact is None or len(series) == 0:
        return []
    t = series.t_s
    any_contact = contact.any(axis=1)
    lowest = lowest_mass_heights_m(series, model, terrain) if lowest_m is None else lowest_m
    normal = np.asarray(terrain.normal)
    force = np.linalg.norm(np.asarray(series.extras["contact_force_n"], dtype=float), axis=2)
    out = []
    airborne_since = None if any_contact[0] else 0
    for i in range(1, len(series)):
        if not any_contact[i]:
            if airborne_since is None:
                airborne_since = i
            continue
        if airborne_since is None:
            continue
        flown = t[i] - t[airborne_since]
        took_off, airborne_since = airborne_since, None
        if flown < MIN_FLIGHT_S:
            continue
        spin = np.linalg.norm(series.angular_velocity_rad_s[took_off : i + 1], axis=1)
        window = (t >= t[i]) & (t <= t[i] + TOUCHDOWN_WINDOW_S)
        first = [
            float(t[window][np.argmax(contact[window, h])]) if contact[window, h].any() else None
            for h in range(2)
        ]
        stagger = abs(first[0] - first[1]) if None not in first else math.nan
        rot = rotation_matrix(series.orientation_wxyz[i])
        along = normal @ rot  # the ground normal's components on body x, y, z
        legs_tilt = math.degrees(math.acos(max(-1.0, min(1.0, float(along[2])))))
        out.append(
            Touchdown(
                t_s=float(t[i]),
                tether_tilt_deg=math.degrees(math.asin(min(1.0, abs(float(along[0]))))),
                legs_tilt_deg=legs_tilt,
                stagger_s=stagger,
                impact_n=(float(force[window, 0].max()), float(force[window, 1].max())),
                on_legs=bool(
                    legs_tilt <= cone_half_angle_deg
                    and lowest[window].min() > -BODY_CONTACT_DEPTH_M
                ),
                angular_speed_rad_s=float(spin[-1]),
                flight_peak_angular_speed_rad_s=float(spin.max()),
            )
        )
    return out


def touchdown_summary(
    series: RunSeries,
    cone_half_angle_deg: float,
    model: RobotModel | None = None,
    terrain: Terrain = FLAT,
) -> dict[str, Metric]:
    """The touchdowns, the time on the body and the tether's time on the terrain, as
    summary metrics."""
    if "contact_force_n" not in series.extras or len(series) == 0:
        return {}
    lowest, tether = ground_clearances_m(series, model, terrain)
    events = touchdowns(series, cone_half_angle_deg, model, lowest, terrain)
    out = {
        "touchdowns": Metric(float(len(events)), "-", "ends of a flight (first contact)"),
        "touchdowns_on_legs": Metric(
            float(sum(e.on_legs for e in events)),
            "-",
            f"touchdowns with the legs within their {cone_half_angle_deg:g} deg cone and no "
            f"lumped mass on the ground for {TOUCHDOWN_WINDOW_S:g} s",
        ),
    }
    dt = np.diff(series.t_s, append=series.t_s[-1])
    out["body_ground_contact_s"] = Metric(
        float(dt[lowest < -BODY_CONTACT_DEPTH_M].sum()),
        "s",
        "time any lumped mass (body or limb tip) is on the ground: a landing on the body",
    )
    out["tether_ground_contact_s"] = Metric(
        float(dt[tether < 0.0].sum()),
        "s",
        "time the tether (between the hemi bodies) lies on or in the terrain",
    )
    for k, e in enumerate(events, start=1):
        rows = (
            (f"touchdown_{k}_t_s", e.t_s, "s", "first contact"),
            (f"flight_{k}_peak_w_rad_s", e.flight_peak_angular_speed_rad_s, "rad/s",
             "largest |w| of the flight ending here"),
            (f"touchdown_{k}_w_rad_s", e.angular_speed_rad_s, "rad/s", "|w| the ground meets"),
            (f"touchdown_{k}_tether_tilt_deg", e.tether_tilt_deg, "deg",
             "tether axis from the ground plane"),
            (f"touchdown_{k}_legs_tilt_deg", e.legs_tilt_deg, "deg",
             "each hemi's legs (belly normal) from the ground normal"),
            (f"touchdown_{k}_stagger_s", e.stagger_s, "s",
             "time between the two hemis' first contacts"),
            (f"touchdown_{k}_impact_a_n", e.impact_n[0], "N", "largest ground force on hemi a"),
            (f"touchdown_{k}_impact_b_n", e.impact_n[1], "N", "largest ground force on hemi b"),
        )  # fmt: skip
        for name, value, unit, meaning in rows:
            out[name] = Metric(value, unit, f"touchdown {k}: {meaning}")
    return out
