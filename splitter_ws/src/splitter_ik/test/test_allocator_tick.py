"""The allocator's ROS-free tick (AllocatorTick): lockstep, hold, fallback, lead, diagnostics."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from splitter_ik.core.allocator import AllocatorConfig, TetherLimbAllocator
from splitter_ik.core.allocator_tick import AllocatorTick, AllocatorTickSettings
from splitter_ik.core.command_lead import CommandLeadConfig
from splitter_ik.core.joint_health import JointHealthConfig
from splitter_ik.core.projection import project_inertia
from splitter_model.model import RobotModel, principal_inertia
from splitter_msgs_py import names
from splitter_msgs_py.core.parameter_fields import parameter_fields
from splitter_msgs_py.core.stamps import MessageValidationError

MODEL = RobotModel()
TICK_NS = 10_000_000  # [ns]
MEASURED = principal_inertia(MODEL, [2.6, 0.25, 0.2])  # [kg m^2]
TARGET = principal_inertia(MODEL, [2.0, 0.3, 0.15])  # [kg m^2]
W = np.array([0.1, 1.0, 0.05])  # [rad/s]


def _no_setpoint_publisher(topic: str) -> int:
    return 0 if topic == names.INERTIA_SETPOINT else 1


def test_lockstep_tick_is_the_allocator_started_from_the_measured_inertia() -> None:
    """The library loop's call gives, bit for bit, what the allocator alone gives."""
    tick = AllocatorTick(MODEL)
    alone = TetherLimbAllocator(MODEL, AllocatorConfig(), project_inertia(MODEL, MEASURED).radii_m)
    for k in range(40):
        t = k * TICK_NS
        setpoint = TARGET if k < 20 else MEASURED
        out = tick.lockstep_tick(t, MEASURED, W * (1 + 0.01 * k), setpoint)
        expected = alone.allocate(t, setpoint, W * (1 + 0.01 * k))
        (got,) = out.commands
        assert got.t_ns == t and out.answered_ns == t
        np.testing.assert_array_equal(got.joint_position, expected.joint_position)
        np.testing.assert_array_equal(got.joint_velocity, expected.joint_velocity)
        assert got.tension_n == expected.tension_n


def test_lockstep_tick_refuses_a_stamp_before_the_last_tick() -> None:
    tick = AllocatorTick(MODEL)
    tick.lockstep_tick(2 * TICK_NS, MEASURED, W, TARGET)
    with pytest.raises(MessageValidationError):
        tick.lockstep_tick(TICK_NS, MEASURED, W, TARGET)


def test_a_rejected_setpoint_is_answered_from_the_last_good() -> None:
    tick = AllocatorTick(MODEL)
    tick.setpoint(0, TARGET)
    out = tick.setpoint(TICK_NS, [math.nan, 1.0, 1.0])
    assert out.rejected is not None and "moments" in out.rejected
    np.testing.assert_array_equal(out.commands[0].requested_inertia_kg_m2, TARGET)
    out = tick.setpoint(2 * TICK_NS, TARGET, frame_id=names.WORLD_FRAME)
    assert out.rejected is not None and "frame_id" in out.rejected
    assert tick.window.rejected == 2
    assert tick.status().values["setpoints_rejected"] == 2


def test_a_rejected_setpoint_answers_no_tick_while_a_stranger_publishes_setpoints() -> None:
    """Two setpoint publishers: a refused setpoint may be the stranger's, its tick waits
    for the MPC's good one (which is then answered as usual)."""
    tick = AllocatorTick(MODEL, publishers=lambda topic: 2)
    tick.setpoint(0, TARGET)
    out = tick.setpoint(TICK_NS, [math.nan, 1.0, 1.0])
    assert out.rejected is not None and out.commands == () and tick.answered_ns == 0
    (good,) = tick.setpoint(TICK_NS, MEASURED).commands
    assert good.t_ns == TICK_NS and tick.answered_ns == TICK_NS
    assert tick.window.rejected == 1


def test_without_any_good_setpoint_the_commanded_radii_are_held() -> None:
    tick = AllocatorTick(MODEL, settings=AllocatorTickSettings(initial_radii_m=(2.5, 0.3, 0.3)))
    out = tick.rejected(names.INERTIA_SETPOINT, 0, "unreadable")
    np.testing.assert_allclose(
        out.commands[0].requested_inertia_kg_m2, principal_inertia(MODEL, [2.5, 0.3, 0.3])
    )
    assert tick.rejected(names.IMU, TICK_NS, "unreadable").commands == ()


def test_a_bad_body_rate_keeps_the_last_good() -> None:
    tick = AllocatorTick(MODEL)
    tick.imu(0, W)
    for bad in ([math.inf, 0.0, 0.0], [2e3, 0.0, 0.0]):
        assert tick.imu(TICK_NS, bad).rejected is not None
    np.testing.assert_array_equal(tick.angular_velocity, W)


def test_the_accelerometer_says_whether_the_feet_hold_the_robot() -> None:
    """Free fall reads no specific force at the COM (the tether is internal); standing
    on the Moon reads g. Held for the dwell, the commands carry no taut limit and no
    tension; a lift-off restores them at once."""
    g_moon = 1.62  # [m/s^2]
    standing = [0.3, 0.1, g_moon]
    dwell_ticks = round(AllocatorConfig().supported_dwell_s * 1e9 / TICK_NS)
    tick = AllocatorTick(MODEL)
    assert not tick.supported  # no accelerometer yet: free fall
    tick.lockstep_tick(0, MEASURED, W, TARGET, [0.0, 0.0, 0.02])
    assert not tick.supported and math.isfinite(tick.last_allocation.tension_n)
    held = [
        tick.lockstep_tick(k * TICK_NS, MEASURED, W, TARGET, standing).commands[0].supported
        for k in range(1, dwell_ticks + 2)
    ]
    assert held == [False] * dwell_ticks + [True]  # from the dwell on
    assert math.isnan(tick.last_allocation.tension_n)
    k = dwell_ticks + 2
    for bad in ([0.0, 0.0, 2e3], [math.nan, 0.0, 0.0]):  # corrupt: the last good kept
        assert tick.imu(k * TICK_NS, W, specific_force_m_s2=bad).rejected is not None
        assert tick.supported
    tick.lockstep_tick(k * TICK_NS, MEASURED, W, TARGET, [0.0, 0.0, 0.01])  # lift-off
    assert not tick.supported and not tick.last_allocation.supported
    tick.lockstep_tick((k + 1) * TICK_NS, MEASURED, W, TARGET, standing)  # lands again
    assert not tick.supported  # the dwell starts over
    no_dwell = dataclasses.replace(tick.config, supported_dwell_s=0.0)
    tick.configure(no_dwell, tick.settings, tick.lead_config)  # live: from the next tick
    assert tick.supported


def test_measured_inertia_ticks_are_answered_once_their_imu_is_in() -> None:
    """No setpoint publisher: each control tick of the state is answered from the hold."""
    tick = AllocatorTick(MODEL, publishers=_no_setpoint_publisher)
    assert tick.measured_inertia(0, MEASURED).commands == ()  # waits for the IMU of 0
    (first,) = tick.imu(0, W).commands
    np.testing.assert_allclose(first.radii_m, project_inertia(MODEL, MEASURED).radii_m)
    tick.imu(TICK_NS // 2, W)
    assert tick.measured_inertia(TICK_NS // 2, MEASURED).commands == ()  # off the grid
    tick.imu(TICK_NS, W)
    (second,) = tick.measured_inertia(TICK_NS, MEASURED).commands  # its IMU came first
    assert second.t_ns == TICK_NS
    assert tick.window.fallback == 1  # the first closed the window it was counted in
    # with a setpoint publisher the state is never answered
    assert AllocatorTick(MODEL).measured_inertia(0, MEASURED).commands == ()


def test_the_diagnostics_window_closes_once_per_period() -> None:
    tick = AllocatorTick(MODEL)
    closed = [tick.lockstep_tick(k * TICK_NS, MEASURED, W, TARGET).closed_window for k in range(21)]
    assert [k for k, w in enumerate(closed) if w is not None] == [0, 10, 20]
    assert closed[10].answered == 10 and closed[10].rate_limited == 10
    status = tick.status(closed[10], extra={"parameter_changes": 0})
    assert status.level == 0 and status.message == "tracking, rate limited"
    assert status.values["parameter_changes"] == 0
    assert status.values["min_tension_margin_n"] >= 0.0


def test_commands_are_stamped_ahead_by_the_latency_measured() -> None:
    """Real time: inputs used 20 ms after their stamp, commands 40 ms ahead (1.5 x 20 + 2 ms,
    in whole periods)."""
    now = {"ns": 0}
    tick = AllocatorTick(
        MODEL, lead=CommandLeadConfig(command_lead=True), clock_ns=lambda: now["ns"]
    )
    stamps = []
    for k in range(5):
        now["ns"] = k * TICK_NS + 2 * TICK_NS
        tick.imu(k * TICK_NS, W)
        stamps += [a.t_ns for a in tick.setpoint(k * TICK_NS, TARGET).commands]
    assert stamps == [(k + 4) * TICK_NS for k in range(5)]
    assert tick.lead.lead_ns == 4 * TICK_NS
    assert tick.status().values["latency_inertia_setpoint_max_ms"] == 20.0


def test_initial_radii_outside_the_model_are_refused() -> None:
    with pytest.raises(ValueError, match="initial_radii_m"):
        AllocatorTick(MODEL, settings=AllocatorTickSettings(initial_radii_m=(5.0, 0.2, 0.2)))


def test_the_parameter_file_sets_exactly_the_core_settings() -> None:
    path = Path(__file__).parents[1] / "config" / "ik_tether_allocator.yaml"
    parameters = yaml.safe_load(path.read_text())["ik_tether_allocator"]["ros__parameters"]
    fields = {
        name: default
        for config in (AllocatorConfig, AllocatorTickSettings, CommandLeadConfig, JointHealthConfig)
        for name, default, _ in parameter_fields(config)
    }
    assert set(parameters) - {"use_sim_time"} <= set(fields)
    for name, value in parameters.items():
        if name != "use_sim_time":
            assert value == (list(fields[name]) if isinstance(value, list) else fields[name])
