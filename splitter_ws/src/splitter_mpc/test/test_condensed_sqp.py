"""The condensed SQP back-end against fatrop's optimum, its own bounds and its merit."""

from __future__ import annotations

import itertools
from dataclasses import replace
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from splitter_model.model import PAPER_INITIAL_RADII_M, RobotModel, principal_inertia
from splitter_mpc.core.condensed_sqp import (
    BufferedFunction,
    CondensedSqpBackend,
    interior_point_qp,
)
from splitter_mpc.core.mpc import (
    MOMENTUM_MPC_SETTINGS,
    InertialMorphingMpc,
    PlanRequest,
    morphing_problem,
    settings_for_weights,
)
from splitter_mpc.core.ocp import MpcWeights
from splitter_mpc.core.solvers import SOLVERS, ProblemInstance, SolverOptions, make_backend

MODEL = RobotModel()
WEIGHTS = MpcWeights(objective="momentum")
I0 = principal_inertia(MODEL, PAPER_INITIAL_RADII_M)  # [kg m^2]
W0 = np.array([-0.3, -0.9, 0.9])  # [rad/s] paper Table I
IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


def _settings(solver: str, **options: object):
    # the spin_stabilization mpc variant's formulation: 25 RK4 steps of 100 ms, no attitude
    base = settings_for_weights(MOMENTUM_MPC_SETTINGS, WEIGHTS)
    opts = SolverOptions(compile=False, max_time_s=30.0, isolated=False, **options)
    return replace(base, solver=solver, options=opts)


def _request(t_ns: int = 0, state: np.ndarray | None = None) -> PlanRequest:
    if state is None:
        state = np.concatenate([W0, IDENTITY, I0])
    horizon = MOMENTUM_MPC_SETTINGS.horizon
    return PlanRequest(t_ns, state, [0.0, 1.0, 0.0], np.tile(IDENTITY, (horizon + 1, 1)), WEIGHTS)


@pytest.fixture(scope="module")
def problem():
    """The first re-plan of the paper's tumble, as the MPC hands it to a back-end."""
    with InertialMorphingMpc(MODEL, _settings("fatrop")) as fatrop:
        data = fatrop.problem(_request())
        reference = fatrop.backend.solve(data)
    assert reference.converged
    return data, reference


@pytest.fixture(scope="module")
def condensed() -> CondensedSqpBackend:
    _, ocp = morphing_problem(MODEL, _settings("condensed_sqp"))
    return make_backend("condensed_sqp", ocp, _settings("condensed_sqp").options)


def test_it_is_a_back_end_by_name() -> None:
    assert "condensed_sqp" in SOLVERS


def test_it_reaches_fatrops_optimum_with_a_consistent_plan(problem, condensed) -> None:
    data, reference = problem
    fatrop_ocp = morphing_problem(MODEL, _settings("fatrop"))[1]
    result = condensed.solve(data)
    assert result.converged and result.usable, result.status
    assert result.cost == pytest.approx(reference.cost, rel=1e-6)
    xs, us = condensed.ocp.split(result.z)
    ref_xs, ref_us = fatrop_ocp.split(reference.z)
    np.testing.assert_allclose(us, ref_us, atol=1e-3)
    np.testing.assert_allclose(xs, ref_xs, atol=1e-4)
    # single shooting: every state is the model's step from the one before (no gap)
    dynamics = condensed.ocp.dynamics()
    for k in range(condensed.ocp.horizon):
        np.testing.assert_allclose(
            np.asarray(dynamics(xs[k], us[k])).ravel(), xs[k + 1], rtol=0, atol=1e-12
        )
    assert result.infeasibility <= 1e-9
    assert np.all(result.z >= data.lbz - 1e-9) and np.all(result.z <= data.ubz + 1e-9)
    # the multipliers come back in the NLP's places: the active radius and rate bounds
    assert result.lam_z.shape == data.lbz.shape and np.any(result.lam_z != 0.0)
    assert result.lam_g.shape == data.lbg.shape


def test_its_iteration_cap_bounds_a_solve_and_each_iteration_lowers_the_cost(problem) -> None:
    data, reference = problem
    _, ocp = morphing_problem(MODEL, _settings("condensed_sqp"))
    costs = []
    for cap in (1, 2, 3, 4, 6):
        backend = make_backend(
            "condensed_sqp", ocp, _settings("condensed_sqp", max_iter=cap).options
        )
        result = backend.solve(data)
        assert result.iterations <= cap
        assert result.usable, result.status  # a capped iterate is a feasible plan
        assert result.status in ("max_iter", "converged")
        costs.append(result.cost)
    # the line search only accepts steps that lower the merit (the iterates stay feasible)
    assert all(b <= a + 1e-9 for a, b in itertools.pairwise(costs))
    assert costs[0] > reference.cost * (1.0 + 1e-6) and costs[-1] >= reference.cost * (1 - 1e-9)


def test_a_warm_start_from_the_shifted_plan_converges_in_fewer_iterations(condensed) -> None:
    with InertialMorphingMpc(MODEL, _settings("condensed_sqp")) as mpc:
        first = mpc.solve(_request())
        assert first.result.converged
        measured = np.concatenate([first.angular_velocity[1], IDENTITY, first.inertia[1]])
        second = mpc.solve(_request(MOMENTUM_MPC_SETTINGS.dt_ns, measured))
    assert second.result.converged
    assert second.result.iterations < first.result.iterations


def test_the_buffered_function_returns_what_a_plain_call_does() -> None:
    x = ca.MX.sym("x", 3)
    f = ca.Function("f", [x], [ca.densify(ca.mtimes(x, x.T) + 1), ca.sin(x)])
    buffered = BufferedFunction(f)
    for value in (np.array([1.0, -2.0, 0.5]), np.array([3.0, 0.0, 4.0])):
        outer, sine = buffered(value)
        np.testing.assert_array_equal(outer, np.asarray(f(value)[0]))
        np.testing.assert_array_equal(sine, np.sin(value))
    sparse = ca.Function("g", [x], [ca.diag(x)])
    with pytest.raises(ValueError, match="dense"):
        BufferedFunction(sparse)


def test_a_warm_start_that_leaves_the_radius_bounds_is_brought_back_within(
    problem, condensed
) -> None:
    data, _ = problem
    ocp = condensed.ocp
    radii = ocp.state.radii_sq
    # every radius pushed outward at its top rate: the rollout soon crosses r_max
    pushed = data.z0.copy()
    for k in range(ocp.horizon):
        rows = ocp.u_index(k)
        pushed[rows.start : rows.start + 3] = data.ubz[rows.start : rows.start + 3]
    start = condensed.feasible_start(replace(data, z0=pushed)).reshape(ocp.horizon, -1)
    s = data.lbz[ocp.x_index(0)][radii] + np.cumsum(start[:, 0:3], axis=0)
    s_max = np.array([data.ubz[ocp.x_index(k)][radii] for k in range(1, ocp.horizon + 1)])
    unclipped = data.lbz[ocp.x_index(0)][radii] + np.cumsum(
        pushed[condensed._u_rows].reshape(ocp.horizon, -1)[:, 0:3], axis=0
    )
    assert np.any(unclipped > s_max)  # the pushed warm start leaves them
    assert np.all(s <= s_max + 1e-12)
    assert np.max(s - s_max) > -1e-9  # it still goes as far out as the bounds allow
    # a feasible warm start (its own plan) is kept as it is
    plan = condensed.solve(data).z
    np.testing.assert_allclose(
        condensed.feasible_start(replace(data, z0=plan)), plan[condensed._u_rows], atol=1e-12
    )


def test_a_solve_from_its_own_optimum_stays_there(problem, condensed) -> None:
    """Near the optimum a step crossing a bound by DAQP's default 1e-6 cost more merit
    than it gained: the line search failed (1 % of a campaign's re-plans)."""
    data, _ = problem
    first = condensed.solve(data)
    again = condensed.solve(replace(data, z0=first.z, lam_g0=first.lam_g, lam_z0=first.lam_z))
    assert again.usable and again.converged, again.status
    assert again.iterations <= 3
    assert again.cost <= first.cost + 1e-9 * abs(first.cost)


def test_a_re_plan_near_its_optimum_takes_its_step(condensed) -> None:
    """A stored re-plan of a campaign tumble (seed 1210734248 at 2.6 s) whose warm start is
    within 5e-5 of the optimum: with DAQP's default feasibility tolerance (1e-6) the step
    crossed a radius bound by 8e-7, which the merit priced above the step's decrease, and
    the line search failed at its first iteration (the previous plan was executed)."""
    stored = np.load(Path(__file__).parent / "data" / "condensed_sqp_near_optimum.npz")
    data = ProblemInstance(**{name: stored[name] for name in stored.files})
    result = condensed.solve(data)
    assert result.usable and result.converged, result.status
    assert result.infeasibility <= 1e-9


def test_a_bounded_back_end_is_solved_in_the_controllers_process() -> None:
    from splitter_mpc.core.solver_worker import SolverWorker
    from splitter_mpc.core.solvers import BOUNDED_SOLVERS

    assert BOUNDED_SOLVERS == ("condensed_sqp",)  # fatrop can freeze (casadi#3857): not it
    isolated = replace(
        _settings("condensed_sqp"),
        options=SolverOptions(compile=False, max_time_s=30.0, isolated=True),
    )
    with InertialMorphingMpc(MODEL, isolated) as mpc:
        assert isinstance(mpc.backend, CondensedSqpBackend)
        assert mpc.deadline_misses == 0
    fatrop = replace(isolated, solver="fatrop")
    with InertialMorphingMpc(MODEL, fatrop) as mpc:
        assert isinstance(mpc.backend, SolverWorker)


def test_the_interior_point_fallback_solves_daqps_qp_form_alike() -> None:
    import daqp

    rng = np.random.default_rng(3)
    n, m = 12, 8
    factor = rng.normal(size=(n, n))
    hessian = factor @ factor.T + np.eye(n)
    gradient = rng.normal(size=n) * 5.0
    rows = rng.normal(size=(m, n))
    upper = np.concatenate([np.full(n, 0.3), np.full(m, 0.5)])
    lower = np.concatenate([np.full(n, -0.3), np.full(m, -1e30)])  # rows: upper only
    upper[2] = 1e30  # one variable unbounded above
    x_ref, _, flag, info = daqp.solve(hessian, gradient, rows, upper, lower)
    assert flag == 1
    x, lam, solved = interior_point_qp(hessian, gradient, rows, upper, lower)
    assert solved
    np.testing.assert_allclose(x, x_ref, atol=1e-7)
    active = np.abs(info["lam"]) > 1e-9
    assert np.any(active)
    np.testing.assert_array_equal(np.sign(lam[active]), np.sign(info["lam"][active]))
    np.testing.assert_allclose(lam, info["lam"], atol=1e-6)


def test_a_degenerate_qp_on_which_daqp_cycles_is_solved_by_the_fallback(monkeypatch) -> None:
    """A stored re-plan of lunar_jumping_robot_errors (50 Euler steps of 10 ms, a slow
    spin): a tension row and its slack's bound active together, DAQP cycles (exit -2)."""
    import splitter_mpc.core.condensed_sqp as condensed_module
    from splitter_mpc.core.mpc import MpcSettings

    stored = np.load(Path(__file__).parent / "data" / "condensed_sqp_degenerate_lunar.npz")
    data = ProblemInstance(**{name: stored[name] for name in stored.files})
    options = SolverOptions(compile=False, max_time_s=30.0, isolated=False)
    settings = replace(
        settings_for_weights(MpcSettings(), MpcWeights()), solver="condensed_sqp", options=options
    )
    _, ocp = morphing_problem(MODEL, settings)
    backend = make_backend("condensed_sqp", ocp, options)
    result = backend.solve(data)
    assert result.usable and result.converged, result.status
    assert backend.fallback_solves >= 1
    # without the fallback the same re-plan fails: DAQP alone cycles on it
    monkeypatch.setattr(
        condensed_module, "interior_point_qp", lambda *qp: (np.zeros(1), np.zeros(1), False)
    )
    alone = make_backend("condensed_sqp", ocp, options).solve(data)
    assert not alone.usable and alone.status.startswith("qp_failed(daqp -2")
