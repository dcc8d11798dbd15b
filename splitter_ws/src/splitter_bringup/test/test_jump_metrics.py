"""Jumping-run figures on a synthetic ballistic series with a known answer."""

from __future__ import annotations

import numpy as np
import pytest

from splitter_bringup.analysis.jump_metrics import jumping_summary, thrust_start_times
from splitter_bringup.analysis.series import RunSeries
from splitter_bringup.scenario.definition import JumpSpec

G_MOON = 9.80665 / 6  # [m/s^2]


def ballistic_series() -> RunSeries:
    """Two jumps: v_x 1 m/s after the first (t = 0), 2 m/s after the second (t = 2 s)."""
    t = np.arange(0, 4.0 + 1e-9, 0.005)
    n = len(t)
    vx = np.where(t < 2.0, 1.0, 2.0)
    vz = np.where(t < 2.0, 1.0 - G_MOON * t, 1.0 - G_MOON * (t - 2.0))
    x = np.cumsum(vx) * 0.005
    force = np.zeros((n, 3))
    force[(t < 0.1) | ((t >= 2.0) & (t < 2.1))] = [160.0, 0.0, 160.0]
    radii = np.column_stack([2.8 - 0.1 * np.sin(t), np.full(n, 0.2), 0.2 + 0.05 * t / t[-1]])
    joints = np.zeros((n, 25))
    joints[:, -1] = 2 * radii[:, 0]
    phases = ["JUMP" if f else "IN_FLIGHT" for f in np.linalg.norm(force, axis=1) > 0]
    return RunSeries(
        t_s=t,
        angular_velocity_rad_s=np.zeros((n, 3)),
        orientation_wxyz=np.tile([1.0, 0, 0, 0], (n, 1)),
        principal_inertia_kg_m2=np.ones((n, 3)),
        inertia_setpoint_kg_m2=np.ones((n, 3)),
        radii_m=radii,
        position_m=np.column_stack([x, np.zeros(n), np.ones(n)]),
        velocity_m_s=np.column_stack([vx, np.zeros(n), vz]),
        joint_position=joints,
        gravity_m_s2=G_MOON,
        gait_phase=phases,
        jump_force_n=force,
    )


def test_jump_onsets_from_the_recorded_thrust() -> None:
    assert thrust_start_times(ballistic_series(), ()) == pytest.approx([0.0, 2.0])


def test_jumping_summary_figures() -> None:
    plan = (JumpSpec(0.0, (160.0, 0.0, 160.0), 0.6), JumpSpec(2.0, (160.0, 0.0, 160.0), 0.6))
    m = jumping_summary(ballistic_series(), plan, {"horizontal_speed_mps": 2.83})
    assert m["horizontal_speed_mps"].value == pytest.approx(np.hypot(2.0, 0.0))
    assert m["horizontal_speed_mps"].paper == 2.83
    assert m["peak_vx_after_jump_1_mps"].value == pytest.approx(1.0)
    assert m["peak_vx_after_jump_2_mps"].value == pytest.approx(2.0)
    assert m["jumps_done"].value == 2
    assert m["range_r_z_m"].value == pytest.approx(0.05)
    assert m["range_tether_length_m"].value == pytest.approx(2 * m["range_r_x_m"].value)
    assert m["mean_horizontal_speed_mps"].value == pytest.approx(1.5, rel=0.01)


def landing_series() -> RunSeries:
    """A scripted launch, flight, jump, flight, landing and rest, with ground forces.

    Phases: LAUNCH 0-0.4 s, IN_FLIGHT 0.4-2 s, JUMP 2-2.5 s, IN_FLIGHT 2.5-3 s,
    LANDING 3-5 s, LANDED from 5 s to the end (6 s). Ground force (both hemis) 150 N
    while pushing (0-0.3 s, 2-2.4 s), 180 N on hemi a / 120 N on hemi b at the landing
    touchdown (4-4.3 s), 15 N standing afterwards.
    """
    t = np.arange(0, 6.0 + 1e-9, 0.01)
    n = len(t)
    phases = np.select(
        [t < 0.4, t < 2.0, t < 2.5, t < 3.0, t < 5.0],
        ["LAUNCH", "IN_FLIGHT", "JUMP", "IN_FLIGHT", "LANDING"],
        "LANDED",
    ).tolist()
    force = np.zeros((n, 2, 3))
    pushing = (t < 0.3) | ((t >= 2.0) & (t < 2.4))
    force[pushing, :, 2] = 150.0
    touchdown = (t >= 4.0) & (t < 4.3)
    force[touchdown, 0, 2] = 180.0
    force[touchdown, 1, 2] = 120.0
    force[t >= 4.3, :, 2] = 15.0
    speed = np.where(t < 4.5, 1.0, 0.01)
    series = ballistic_series()
    return RunSeries(
        t_s=t,
        angular_velocity_rad_s=np.column_stack([np.where(t < 4.5, 0.2, 0.0), *[np.zeros(n)] * 2]),
        orientation_wxyz=np.tile([1.0, 0, 0, 0], (n, 1)),
        principal_inertia_kg_m2=np.ones((n, 3)),
        inertia_setpoint_kg_m2=np.ones((n, 3)),
        radii_m=np.tile(series.radii_m[0], (n, 1)),
        position_m=np.zeros((n, 3)),
        velocity_m_s=np.column_stack([speed, np.zeros(n), np.zeros(n)]),
        joint_position=np.zeros((n, 25)),
        gravity_m_s2=G_MOON,
        gait_phase=phases,
        extras={"contact_force_n": force},
    )


def test_gait_summary_of_a_scripted_landing() -> None:
    from splitter_bringup.analysis.jump_metrics import flight_durations, gait_summary, phase_spans

    series = landing_series()
    spans = phase_spans(series.t_s, series.gait_phase)
    assert [s[0] for s in spans] == [
        "LAUNCH",
        "IN_FLIGHT",
        "JUMP",
        "IN_FLIGHT",
        "LANDING",
        "LANDED",
    ]
    m = {k: v.value for k, v in gait_summary(series, planned_jumps=2).items()}
    assert m["landed_at_s"] == pytest.approx(5.0)
    assert m["phase_changes"] == 5
    assert m["shortest_phase_s"] == pytest.approx(0.4)  # LAUNCH; JUMP (0.5 s) is exempt
    assert m["final_phase"] == 1.0
    assert m["rest_speed_max_mps"] == pytest.approx(0.01)
    assert m["rest_angular_speed_max_rad_s"] == 0.0
    assert m["peak_contact_force_a_n"] == pytest.approx(180.0)
    assert m["peak_landing_force_a_n"] == pytest.approx(180.0)
    assert m["peak_landing_force_b_n"] == pytest.approx(120.0)  # the pushes were before
    assert m["peak_contact_force_b_n"] == pytest.approx(150.0)
    assert m["limb_force_limit_n"] == pytest.approx(20.0 * 9.80665)
    # flights: 0.3-2.0 s and 2.4-4.0 s without contact
    assert flight_durations(series.t_s, series.extras["contact_force_n"]) == pytest.approx(
        [1.7, 1.6], abs=0.011
    )
    assert m["flight_1_s"] == pytest.approx(1.7, abs=0.011)
