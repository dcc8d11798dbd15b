"""Touchdown reports from a run's series: tilts, stagger, impact, legs or body."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from splitter_bringup.analysis.series import RunSeries
from splitter_bringup.analysis.touchdowns import touchdown_summary, touchdowns
from splitter_model.kinematics import joint_positions_from_radii
from splitter_model.model import RobotModel
from splitter_model.terrain import Step, Terrain

MODEL = RobotModel()
DT = 0.005  # [s]
CONE_DEG = 60.0  # [deg]


def _series(pitch_deg: float, roll_deg: float, com_height_m: float) -> RunSeries:
    """1 s of flight, then hemi a touches at 1.0 s with 150 N and hemi b at 1.1 s with 180 N;
    the robot pitched about y (the tether tilts) and rolled about x (the legs tilt)."""
    t = np.arange(0.0, 2.0, DT)
    n = len(t)
    xyzw = Rotation.from_euler("YX", [pitch_deg, roll_deg], degrees=True).as_quat()
    q = np.tile([xyzw[3], *xyzw[:3]], (n, 1))
    contact = np.zeros((n, 2, 3))
    contact[t >= 1.0 - 1e-9, 0, 2] = 150.0
    contact[t >= 1.1 - 1e-9, 1, 2] = 180.0
    position = np.zeros((n, 3))
    position[:, 2] = np.where(t < 1.0, 3.0, com_height_m)
    joints = np.tile(joint_positions_from_radii(MODEL, (2.8, 0.2, 0.2)), (n, 1))
    zeros = np.zeros((n, 3))
    w = np.zeros((n, 3))
    w[:, 2] = np.where(t < 0.5, 0.4, 0.3)  # [rad/s] a spin slowed in flight
    return RunSeries(
        t, w, q, zeros, zeros, zeros, position, zeros, joints, 1.62,
        extras={"contact_force_n": contact},
    )  # fmt: skip


def test_a_tilted_staggered_touchdown_on_the_legs() -> None:
    [event] = touchdowns(_series(10.0, 20.0, 1.0), CONE_DEG, MODEL)  # lower hemi 0.5 m up
    assert event.t_s == pytest.approx(1.0)
    assert event.tether_tilt_deg == pytest.approx(10.0)
    # body z from the vertical (pitch about y, then roll about the new x): cos(10) cos(20)
    expected = math.degrees(math.acos(math.cos(math.radians(10)) * math.cos(math.radians(20))))
    assert event.legs_tilt_deg == pytest.approx(expected)
    assert event.stagger_s == pytest.approx(0.1)
    assert event.impact_n == (150.0, 180.0)
    assert event.on_legs
    assert event.angular_speed_rad_s == 0.3 and event.flight_peak_angular_speed_rad_s == 0.4


def test_a_touchdown_outside_the_cone_or_on_a_mass_is_on_the_body() -> None:
    assert not touchdowns(_series(0.0, 70.0, 0.5), CONE_DEG, MODEL)[0].on_legs
    # Level, but the centre of mass 0.1 m up: the lower limb tips (0.2 m) are in the ground.
    low = _series(0.0, 0.0, 0.1)
    assert not touchdowns(low, CONE_DEG, MODEL)[0].on_legs
    summary = touchdown_summary(low, CONE_DEG, MODEL)
    assert summary["touchdowns"].value == 1.0 and summary["touchdowns_on_legs"].value == 0.0
    assert summary["body_ground_contact_s"].value == pytest.approx(1.0, abs=2 * DT)
    assert summary["touchdown_1_impact_b_n"].value == 180.0
    high = touchdown_summary(_series(0.0, 0.0, 0.5), CONE_DEG, MODEL)
    assert high["touchdowns_on_legs"].value == 1.0 and high["body_ground_contact_s"].value == 0.0


def test_the_gait_figure_marks_each_touchdown(tmp_path) -> None:
    from splitter_bringup.figures.plots import plot_gait

    series = _series(0.0, 0.0, 0.1)
    series.gait_phase = ["IN_FLIGHT"] * len(series)
    events = touchdowns(series, CONE_DEG, MODEL)
    assert [e.on_legs for e in events] == [False]
    path = plot_gait(series, tmp_path / "gait.png", "touchdowns", 196.1, events)
    assert path.stat().st_size > 10_000


def test_tilts_are_measured_from_the_terrain_and_the_tether_on_a_step_is_reported() -> None:
    series = _series(10.0, 0.0, 1.0)  # pitched 10 deg: body x points down towards +x
    slope = Terrain(10.0, 180.0)  # rises towards -x: the robot lies along it
    [level] = touchdowns(series, CONE_DEG, MODEL)
    [sloped] = touchdowns(series, CONE_DEG, MODEL, terrain=slope)
    assert level.tether_tilt_deg == pytest.approx(10.0)
    assert sloped.tether_tilt_deg == pytest.approx(0.0, abs=1e-6)
    assert sloped.legs_tilt_deg == pytest.approx(0.0, abs=1e-4)
    # a 1.2 m step between the hemis: the tether (1 m up at the COM) crosses it
    ridge = Terrain(0.0, 0.0, (Step(-0.5, 0.5, -5.0, 5.0, 1.2),))
    flat = touchdown_summary(_series(0.0, 0.0, 1.0), CONE_DEG, MODEL)
    crossed = touchdown_summary(_series(0.0, 0.0, 1.0), CONE_DEG, MODEL, ridge)
    assert flat["tether_ground_contact_s"].value == 0.0
    assert crossed["tether_ground_contact_s"].value == pytest.approx(1.0, abs=0.01)
