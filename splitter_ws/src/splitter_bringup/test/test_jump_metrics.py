"""Jumping-run figures on a synthetic ballistic series with a known answer."""

from __future__ import annotations

import numpy as np
import pytest

from splitter_bringup.core.jump_metrics import jumping_summary, thrust_start_times
from splitter_bringup.core.scenario import JumpSpec
from splitter_bringup.core.series import RunSeries

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
