"""The simulator's decisions between steps: jump wrench bounds, lockstep waits, real-time pace."""

from __future__ import annotations

import numpy as np
import pytest

from splitter_model.model import RobotModel
from splitter_sim.core.simulator import InitialState, SimConfig, Simulator
from splitter_sim.core.stepping import (
    MAX_JUMP_FORCE_N,
    REAL_TIME_MAX_CATCH_UP,
    JumpThrust,
    LockstepWait,
    RealTimePacer,
    check_jump_wrench,
    jump_thrust,
    pushing_hemi,
)

MS = 1_000_000  # [ns]


def test_a_jump_wrench_beyond_its_bounds_is_refused_without_overflow() -> None:
    check_jump_wrench([0.0, 40.0, 40.0], [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match=r"wrench\.force"):
        check_jump_wrench([MAX_JUMP_FORCE_N * 1.01, 0.0, 0.0], [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match=r"wrench\.torque"):
        check_jump_wrench([0.0, 0.0, 0.0], [1e300, 1e300, 0.0])  # the norm would overflow


def test_the_torque_about_the_com_names_the_pushing_hemi() -> None:
    sim = Simulator(RobotModel(), SimConfig(), InitialState())
    state = sim.state()
    force = np.array([0.0, 0.0, 40.0])  # [N]
    for hemi, body in (("a", 0), ("b", 5)):
        lever = state.mass_positions_world_m[body] - state.position_m
        assert pushing_hemi(state, force, np.cross(lever, force)) == hemi
    assert pushing_hemi(state, force, np.zeros(3)) == "auto"
    assert pushing_hemi(None, force, np.ones(3)) == "auto"


def test_a_wrench_of_two_pushes_is_split_back_into_them() -> None:
    """The gait encodes F_a at hemi a and F_b at hemi b with levers +-d/2; the split gives
    back their parts across the tether and shares the part along it."""
    sim = Simulator(RobotModel(), SimConfig(), InitialState(radii_m=(2.5, 0.3, 0.15)))
    state = sim.state()
    body_a, body_b = state.mass_positions_world_m[[0, 5]]
    half = 0.5 * (body_a - body_b)
    axis = half / np.linalg.norm(half)
    force_a, force_b = np.array([20.0, 5.0, 200.0]), np.array([-20.0, 30.0, 120.0])
    force = force_a + force_b
    torque = np.cross(half, force_a) - np.cross(half, force_b)
    thrust = jump_thrust(state, force, torque)
    assert thrust.hemi == "auto" and thrust.per_hemi is not None
    got_a, got_b = thrust.per_hemi
    np.testing.assert_allclose(got_a + got_b, force, atol=1e-12)
    np.testing.assert_allclose(np.cross(half, got_a) - np.cross(half, got_b), torque, atol=1e-9)
    across = np.eye(3) - np.outer(axis, axis)
    np.testing.assert_allclose(across @ got_a, across @ force_a, atol=1e-9)
    np.testing.assert_allclose(got_a @ axis, 0.5 * force @ axis, atol=1e-9)
    # One hemi's push stays that hemi's; no torque is "auto".
    assert jump_thrust(state, force, np.cross(half, force)) == JumpThrust("a")
    assert jump_thrust(state, force, np.cross(-half, force)) == JumpThrust("b")
    assert jump_thrust(state, force, np.zeros(3)) == JumpThrust("auto")
    assert jump_thrust(None, force, torque) == JumpThrust("auto")


def test_unequal_pushes_launch_a_spin_with_the_angular_impulse_of_the_wrench() -> None:
    """Hemi a pushes 200 N up, hemi b 120 N, under lunar gravity until each leaves its
    stroke: the robot leaves with the angular impulse of the pushes (rectangle rule)
    and spins about the horizontal axis across the tether, hemi a rising."""
    from splitter_sim.core.tick import SimulatorTick

    model = RobotModel()
    # without the ride posture the push starts at once, from where the robot stands
    config = SimConfig(gravity_m_s2=1.62, compliant_legs=True, leg_posture_stiffness_n_m=0.0)
    tick = SimulatorTick(Simulator(model, config, InitialState(position_m=(0.0, 0.0, 0.25))))
    force_a, force_b = np.array([0.0, 0.0, 200.0]), np.array([0.0, 0.0, 120.0])
    angular_impulse = np.zeros(3)
    pushed = np.stack([force_a, force_b])  # [N] the first step's thrust: both in stance
    for _ in range(int(0.3 / 0.005)):
        state = tick.state()
        body_a, body_b = state.mass_positions_world_m[[0, 5]]
        half = 0.5 * (body_a - body_b)
        tick.command_jump(state.t_ns, force_a + force_b, np.cross(half, force_a - force_b))
        levers = state.mass_positions_world_m[[0, 5]] - state.position_m
        angular_impulse += 0.005 * (np.cross(levers[0], pushed[0]) + np.cross(levers[1], pushed[1]))
        tick.step()
        # The thrust of the next step (the command in force), until a hemi leaves its stroke.
        pushed = tick.state().leg_force_n
    end = tick.state()
    np.testing.assert_allclose(end.angular_momentum_world, angular_impulse, rtol=0.03)
    w = end.angular_velocity_rad_s
    assert w[1] < -0.1 and abs(w[0]) < 1e-6 and abs(w[2]) < 1e-6  # hemi a (+x) rises: -y
    assert np.linalg.norm(angular_impulse) > 10.0  # [N m s] both pushed a while


def test_a_shared_push_loses_the_half_of_a_hemi_out_of_reach() -> None:
    """ "auto": each hemi's legs push half. Tilted so that hemi a (+x) is beyond the legs'
    stroke, hemi b pushes its half alone; legs cannot hand their force to the other's."""
    from scipy.spatial.transform import Rotation

    xyzw = Rotation.from_euler("y", -12.0, degrees=True).as_quat()  # hemi a up
    initial = InitialState(position_m=(0.0, 0.0, 0.8), orientation_wxyz=(xyzw[3], *xyzw[:3]))
    sim = Simulator(RobotModel(), SimConfig(gravity_m_s2=1.62), initial)
    heights = sim.state().mass_positions_world_m[:, 2]
    assert heights[:5].min() > 0.4 > heights[5:].min()  # hemi a out of reach, b within
    force = np.array([40.0, 0.0, 320.0])  # [N]
    sim.command_jump_force(force, "auto")
    np.testing.assert_array_equal(sim.state().leg_force_n[0], 0.0)
    np.testing.assert_allclose(sim.state().leg_force_n[1], force / 2.0)


def test_lockstep_steps_when_every_topic_answered_or_after_the_timeout() -> None:
    wait = LockstepWait(("joints", "jump"), timeout_s=1.0)
    has_publisher = {"joints": True, "jump": False}.get
    waiting = wait.waiting_for(10 * MS, has_publisher)
    assert waiting == ["joints"]  # a topic without a publisher is not waited for
    assert wait.may_step(waiting, 0.0) == (False, None)
    assert wait.may_step(waiting, 0.5) == (False, None)
    assert wait.may_step(waiting, 1.2) == (True, pytest.approx(1.2)) and wait.timeouts == 1
    wait.arrived("joints", 20 * MS)
    assert wait.may_step(wait.waiting_for(20 * MS, has_publisher), 1.3) == (True, None)


def test_the_real_time_pace_follows_the_wall_clock_and_caps_its_catch_up() -> None:
    pacer = RealTimePacer(rate_factor=2.0, dt_ns=5 * MS)
    pacer.restart(8.0, 0)
    assert pacer.steps_due(8.0, 0) == (0, False)
    assert pacer.steps_due(8.015625, 0) == (6, False)  # 15.6 ms wall x2 = 31.25 ms simulated
    assert pacer.steps_due(8.015625, 10 * MS) == (4, False)  # two of them already taken
    assert pacer.steps_due(9.0, 0) == (REAL_TIME_MAX_CATCH_UP, True)  # 400 due


def test_the_tick_drives_the_simulator_as_the_direct_calls_do() -> None:
    """SimulatorTick (what the node and the library loop drive) is the bare simulator
    with the commands of each tick, bit for bit; its stamp rules refuse a stale command."""
    from splitter_model.kinematics import joint_positions_from_radii
    from splitter_msgs_py import names
    from splitter_msgs_py.core.stamps import MessageValidationError
    from splitter_sim.core.tick import SimulatorTick

    model = RobotModel()

    def make() -> Simulator:
        initial = InitialState(position_m=(0.0, 0.0, 0.45), radii_m=(2.8, 0.2, 0.2))
        return Simulator(model, SimConfig(gravity_m_s2=1.62), initial)

    bare, tick = make(), SimulatorTick(make())
    target = joint_positions_from_radii(model, (2.7, 0.25, 0.2))
    for _ in range(60):
        state = bare.state()
        assert tick.state().t_ns == state.t_ns
        if state.t_ns % (10 * MS) == 0:
            force = np.array([5.0, 0.0, 40.0])
            torque = np.cross(state.mass_positions_world_m[5] - state.position_m, force)
            bare.command_jump_force(force, pushing_hemi(state, force, torque))
            tick.command_jump(state.t_ns, force, torque)
            bare.command_joints(target)
            tick.command_joints(state.t_ns, target)
        bare.step()
        tick.step()
    for name in ("position_m", "orientation_wxyz", "joint_position", "contact_force_n"):
        np.testing.assert_array_equal(getattr(tick.state(), name), getattr(bare.state(), name))
    now = tick.admit(names.JOINT_COMMANDS, tick.time_ns)
    with pytest.raises(MessageValidationError, match="earlier"):
        tick.admit(names.JOINT_COMMANDS, now - 5 * MS)
    with pytest.raises(MessageValidationError, match="ahead"):
        tick.admit(names.JUMP_COMMAND, now + 1)
