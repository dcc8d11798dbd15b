"""The simulator's decisions between steps: jump wrench bounds, lockstep waits, real-time pace."""

from __future__ import annotations

import numpy as np
import pytest

from splitter_model.model import RobotModel
from splitter_sim.core.simulator import InitialState, SimConfig, Simulator
from splitter_sim.core.stepping import (
    MAX_JUMP_FORCE_N,
    REAL_TIME_MAX_CATCH_UP,
    LockstepWait,
    RealTimePacer,
    check_jump_wrench,
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
