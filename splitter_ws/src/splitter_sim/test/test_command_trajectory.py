"""Joint commands as stamped trajectory points: followed at their stamps, queued, blended."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from splitter_model.actuators import TETHER_INDEX
from splitter_model.kinematics import joint_positions_from_radii
from splitter_model.model import RobotModel
from splitter_sim.core import actuators
from splitter_sim.core.simulator import InitialState, SimConfig, Simulator
from splitter_sim.core.stepping import CommandQueue, check_trajectory_stamp

MODEL = RobotModel()
MS = 1_000_000  # [ns]
TETHER = TETHER_INDEX


def _sim(**config) -> Simulator:
    return Simulator(
        MODEL,
        SimConfig(ground_contact=False, **config),
        InitialState(radii_m=(2.8, 0.2, 0.2)),
        compiled=False,
    )


def _ramp(sim: Simulator, speed: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    q = joint_positions_from_radii(MODEL, (2.8, 0.2, 0.2)).astype(float)
    v = np.zeros(25)
    v[TETHER] = speed  # [m/s] paying out
    return q, v


def test_a_command_is_followed_from_its_stamp_not_from_its_arrival() -> None:
    on_time, late = _sim(command_extrapolation_s=1.0), _sim(command_extrapolation_s=1.0)
    q, v = _ramp(on_time, speed=0.05)
    on_time.command_joints(q, v, stamp_ns=0)
    for _ in range(4):
        on_time.step()
        late.step()
    late.command_joints(q, v, stamp_ns=0)  # the same point, 20 ms late
    target_late = late._servo_target()
    target_on_time = on_time._servo_target()
    # the reference is where the trajectory is now (plus a blend offset that starts at
    # the servos' reference and fades): its velocity is the trajectory's
    assert target_late[1][TETHER] == pytest.approx(target_on_time[1][TETHER], abs=1e-9)
    for _ in range(100):
        on_time.step()
        late.step()
    # both servos on the same trajectory again: the late start is made up
    assert late.state().joint_position[TETHER] == pytest.approx(
        on_time.state().joint_position[TETHER], abs=1e-9
    )
    restarted = _sim(command_extrapolation_s=1.0)  # the old semantics: from the arrival
    for _ in range(4):
        restarted.step()
    restarted.command_joints(q, v)
    for _ in range(100):
        restarted.step()
    behind = on_time.state().joint_position[TETHER] - restarted.state().joint_position[TETHER]
    assert behind == pytest.approx(0.05 * 0.02, rel=1e-3)


def test_a_command_from_the_future_is_refused() -> None:
    sim = _sim()
    q, v = _ramp(sim)
    with pytest.raises(ValueError, match="later than the simulated time"):
        sim.command_joints(q, v, stamp_ns=5 * MS)


def test_a_late_point_moves_the_reference_continuously() -> None:
    sim = _sim(command_extrapolation_s=0.25)
    q, v = _ramp(sim)
    sim.command_joints(q, v, stamp_ns=0)
    for _ in range(6):
        sim.step()
    before = sim._servo_target()[0].copy()
    q2 = q + v * 0.01
    v2 = v.copy()
    v2[TETHER] = 0.2  # the plan slowed the reel at t = 10 ms; the point arrives at 30 ms
    sim.command_joints(q2, v2, stamp_ns=10 * MS)
    after = sim._servo_target()[0]
    assert after[TETHER] == pytest.approx(before[TETHER], abs=1e-12)  # no jump
    # without the blend the reference would jump by (0.5 - 0.2) m/s x 20 ms
    jump = (q2 + v2 * 0.02)[TETHER] - before[TETHER]
    assert abs(jump) == pytest.approx(0.3 * 0.02, rel=1e-6)


def test_blend_offsets_fade_to_zero_with_position_continuous() -> None:
    sim = _sim()
    lim = sim.joint_limits
    dq = np.full(25, 1e-3)
    blend = actuators.LateCommandBlend(0, dq, 0.04)
    q0 = np.clip(np.zeros(25), lim.position_min, lim.position_max)
    v0 = np.zeros(25)
    start = blend.apply(0, q0, v0, lim)[0]
    np.testing.assert_allclose(start, np.clip(q0 + dq, lim.position_min, lim.position_max))
    end = blend.apply(40 * MS, q0, v0, lim)[0]
    np.testing.assert_allclose(end, q0)
    assert not blend.active(40 * MS) and blend.active(39 * MS)


def test_corner_blend_is_continuous_with_constant_acceleration() -> None:
    q0, v0, dv, tau = np.array([1.0]), np.array([0.5]), np.array([-0.3]), 0.01
    # before the corner: incoming line (q0 + v0 t, t from the blend start at -tau/2)
    eps = 1e-9
    q_in, v_in = actuators.corner_blend(q0 + v0 * (tau / 2), v0, dv, tau / 2 - eps, tau)
    # after the corner: the outgoing line starts at the corner position
    corner = q0 + v0 * (tau / 2)
    q_out, v_out = actuators.corner_blend(corner, v0 + dv, dv, -(tau / 2) + eps, tau)
    assert q_in == pytest.approx(q_out, abs=1e-8)
    assert v_in == pytest.approx(v_out, abs=1e-6)
    # at the blend's ends it meets the lines with their velocities
    assert actuators.corner_blend(q0, v0, dv, 0.0, tau)[1] == pytest.approx(v0)
    assert actuators.corner_blend(corner, v0 + dv, dv, -0.0, tau)[1] == pytest.approx(v0 + dv)


def test_a_previewed_corner_is_rounded_and_an_unpreviewed_one_is_not() -> None:
    rounded, sharp = _sim(knot_blend_s=0.01), _sim(knot_blend_s=0.01)
    q, v = _ramp(rounded)
    for sim in (rounded, sharp):
        sim.command_joints(q, v, stamp_ns=0)
        sim.step()  # t = 5 ms: the next point (t = 10 ms) is known to one of them
    v2 = v.copy()
    v2[TETHER] = 0.0
    rounded.preview_next_point(10 * MS, v2)
    assert rounded._servo_target()[1][TETHER] == pytest.approx(0.5, abs=1e-9)  # blend starts
    rounded.step()
    sharp.step()
    for sim in (rounded, sharp):
        sim.command_joints(q + v * 0.01, v2, stamp_ns=10 * MS)
    # at the corner the rounded reference is half-way in velocity
    assert rounded._servo_target()[1][TETHER] == pytest.approx(0.25, abs=1e-9)
    assert sharp._servo_target()[1][TETHER] == pytest.approx(0.0, abs=1e-12)


def test_command_queue_applies_points_at_their_stamps_and_replans() -> None:
    queue = CommandQueue()
    queue.push(20 * MS, "a")
    queue.push(30 * MS, "b")
    queue.push(40 * MS, "c")
    assert queue.peek() == (20 * MS, "a")
    assert queue.due(15 * MS) is None
    assert queue.due(20 * MS) == (20 * MS, "a")
    queue.push(30 * MS, "b2")  # a newer plan from 30 ms on replaces b and c
    assert len(queue) == 1
    assert queue.due(100 * MS) == (30 * MS, "b2")
    queue.push(50 * MS, "d")
    queue.drop_from(50 * MS)
    assert queue.peek() is None


def test_trajectory_stamps_may_replan_ahead_but_not_the_past() -> None:
    check_trajectory_stamp(30 * MS, applied_ns=20 * MS, now_ns=25 * MS, max_lead_ns=100 * MS)
    with pytest.raises(ValueError, match="earlier than the point in effect"):
        check_trajectory_stamp(10 * MS, applied_ns=20 * MS, now_ns=25 * MS, max_lead_ns=MS)
    with pytest.raises(ValueError, match="ahead of the simulated time"):
        check_trajectory_stamp(200 * MS, applied_ns=0, now_ns=25 * MS, max_lead_ns=100 * MS)


def test_simconfig_refuses_negative_trajectory_settings() -> None:
    with pytest.raises(ValueError, match="command_extrapolation_s"):
        SimConfig(command_extrapolation_s=-1.0)
    with pytest.raises(ValueError, match="knot_blend_s"):
        dataclasses.replace(SimConfig(), knot_blend_s=-0.01)
