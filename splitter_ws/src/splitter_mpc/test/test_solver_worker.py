"""Solves bounded in wall time: the back-end in a worker process, killed at its deadline."""

from __future__ import annotations

import os
import time
from dataclasses import replace
from functools import partial

import numpy as np
import pytest

from splitter_model.model import PAPER_INITIAL_RADII_M, RobotModel, principal_inertia
from splitter_mpc.core.controller import ControllerConfig, MorphingController
from splitter_mpc.core.mpc import InertialMorphingMpc, MpcSettings, PlanRequest, build_backend
from splitter_mpc.core.ocp import MpcWeights
from splitter_mpc.core.solver_worker import (
    STATUS_ABANDONED,
    STATUS_DEADLINE_MISSED,
    STATUS_NON_FINITE_DATA,
    STATUS_WORKER_DIED,
    FaultInjection,
    SolverWorker,
    WorkerStartError,
)
from splitter_mpc.core.solvers import SolverOptions

MODEL = RobotModel()
MS = 1_000_000  # [ns]
I0 = principal_inertia(MODEL, PAPER_INITIAL_RADII_M)
W0 = np.array([-0.3, -0.9, 0.9])  # [rad/s]
Q0 = np.array([1.0, 0.0, 0.0, 0.0])
DEADLINE_S = 1.0  # [s] far above a solve of this small problem (~20 ms), far below a hang
KILL_ALLOWANCE_S = 0.5  # [s] the time to notice the miss and kill the worker, with margin
SETTINGS = MpcSettings(
    horizon=10,
    dt_s=0.05,
    integrator="rk4",
    attitude_states=False,
    options=SolverOptions(compile=False, max_time_s=DEADLINE_S, isolated=False),
)


@pytest.fixture(scope="module")
def local_mpc() -> InertialMorphingMpc:
    """The same problem with the back-end in this process (the reference answers)."""
    return InertialMorphingMpc(MODEL, SETTINGS)


def problem(mpc: InertialMorphingMpc, t_ms: int = 0):
    state = np.concatenate([W0, Q0, I0])
    q_ref = np.tile(Q0, (11, 1))
    return mpc.problem(PlanRequest(t_ms * MS, state, [0.0, 1.0, 0.0], q_ref, MpcWeights()))


def worker(**faults) -> SolverWorker:
    factory = partial(build_backend, MODEL, SETTINGS)
    return SolverWorker(FaultInjection(factory, **faults) if faults else factory, DEADLINE_S)


def test_a_worker_answers_exactly_what_the_back_end_in_this_process_does(local_mpc) -> None:
    data = problem(local_mpc)
    expected = local_mpc.backend.solve(data)
    with worker() as w:
        got = w.solve(data)
    assert got.usable and got.status == expected.status
    np.testing.assert_array_equal(got.z, expected.z)  # the same code on the same numbers
    assert got.iterations == expected.iterations and got.cost == expected.cost


def test_a_hanging_solve_is_abandoned_at_its_deadline_and_the_next_one_is_solved(
    local_mpc,
) -> None:
    data = problem(local_mpc)
    with worker(hang_solves=(2,)) as w:
        assert w.solve(data).usable
        first_pid = w.pid
        started = time.monotonic()
        missed = w.solve(data)
        waited = time.monotonic() - started
        assert missed.status == STATUS_DEADLINE_MISSED and not missed.usable
        assert DEADLINE_S <= waited <= DEADLINE_S + KILL_ALLOWANCE_S
        assert w.deadline_misses == 1 and w.restarts == 1 and w.pid != first_pid
        with pytest.raises(ProcessLookupError):
            os.kill(first_pid, 0)  # the frozen worker is gone, not left spinning
        assert w.solve(data).usable  # a fresh worker (its first solve does not hang)


def test_a_worker_that_dies_in_a_solve_is_replaced(local_mpc) -> None:
    data = problem(local_mpc)
    with worker(crash_solves=(2,)) as w:
        assert w.solve(data).usable
        assert w.solve(data).status == STATUS_WORKER_DIED
        assert w.solve(data).usable and w.restarts == 1 and w.deadline_misses == 0


def test_non_finite_problem_data_never_reaches_the_solver(local_mpc) -> None:
    data = problem(local_mpc)
    bad = replace(data, p=np.where(np.arange(data.p.size) == 3, np.nan, data.p))
    with worker(crash_solves=(1,)) as w:  # a solve that reached the worker would kill it
        result = w.solve(bad)
        assert result.status == STATUS_NON_FINITE_DATA and not result.usable
        infinite_start = replace(data, z0=np.full_like(data.z0, np.inf))
        assert w.solve(infinite_start).status == STATUS_NON_FINITE_DATA
        assert w.restarts == 0
    # the MPC checks its problem before any back-end sees it (here: an infinite I_nom)
    state = np.concatenate([W0, Q0, I0])
    q_ref = np.tile(Q0, (11, 1))
    nominal = [np.inf, 1.0, 1.0]
    plan = local_mpc.solve(
        PlanRequest(0, state, [0.0, 1.0, 0.0], q_ref, MpcWeights(), nominal_inertia_kg_m2=nominal)
    )
    assert plan.result.status == STATUS_NON_FINITE_DATA and not plan.result.usable


def test_a_stop_request_ends_the_wait_for_a_hanging_solve(local_mpc) -> None:
    data = problem(local_mpc)
    with worker(hang_solves=(1,)) as w:
        asked_at = time.monotonic() + 0.2
        w.abandon = lambda: time.monotonic() > asked_at
        started = time.monotonic()
        result = w.solve(data)
        assert result.status == STATUS_ABANDONED
        assert time.monotonic() - started < 0.2 + KILL_ALLOWANCE_S
        assert w.deadline_misses == 0  # a stop is not a missed deadline


def test_a_back_end_that_cannot_be_built_is_a_clear_error() -> None:
    bad = replace(SETTINGS, solver="fatrop", horizon=2, options=replace(SETTINGS.options))
    with pytest.raises(WorkerStartError, match="could not build"):
        SolverWorker(partial(build_backend, "not a model", bad), DEADLINE_S)


def test_the_controller_executes_its_previous_plan_through_a_hanging_solve() -> None:
    """Issue 13: an injected hanging solve; the controller continues within its deadline."""
    settings = replace(SETTINGS, options=replace(SETTINGS.options, isolated=True))
    mpc = InertialMorphingMpc(MODEL, replace(settings, options=replace(settings.options)))
    mpc.backend.close()
    mpc.backend = SolverWorker(
        FaultInjection(partial(build_backend, MODEL, SETTINGS), hang_solves=(2,)), DEADLINE_S
    )
    with MorphingController(MODEL, ControllerConfig(mpc=mpc.settings), mpc) as ctl:
        ctl.set_reference(0, [0.0, 1.0, 0.0], Q0)
        ctl.on_state(0, W0, Q0, I0, "IN_FLIGHT")
        plan = ctl.plan
        assert ctl.status.solve_ok
        for t_ms in range(10, 100, 10):
            ctl.on_state(t_ms * MS, W0, Q0, I0, "IN_FLIGHT")
        started = time.monotonic()
        setpoint = ctl.on_state(100 * MS, W0, Q0, I0, "IN_FLIGHT")  # the hanging re-plan
        assert time.monotonic() - started <= DEADLINE_S + KILL_ALLOWANCE_S
        status = ctl.status
        assert status.solve_status == STATUS_DEADLINE_MISSED and status.deadline_misses == 1
        assert ctl.plan is plan  # the shifted previous plan is executed
        np.testing.assert_allclose(setpoint, plan.setpoint_at(100 * MS, 10 * MS))
        ctl.on_state(200 * MS, W0, Q0, I0, "IN_FLIGHT")
        assert ctl.status.solve_ok and ctl.plan is not plan and ctl.status.failures == 1
