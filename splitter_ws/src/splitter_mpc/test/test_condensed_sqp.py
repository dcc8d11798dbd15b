"""The condensed SQP back-end against fatrop's optimum, its own bounds and its merit."""

from __future__ import annotations

import itertools
from dataclasses import replace

import casadi as ca
import numpy as np
import pytest

from splitter_model.model import PAPER_INITIAL_RADII_M, RobotModel, principal_inertia
from splitter_mpc.core.condensed_sqp import BufferedFunction, CondensedSqpBackend
from splitter_mpc.core.mpc import (
    MOMENTUM_MPC_SETTINGS,
    InertialMorphingMpc,
    PlanRequest,
    morphing_problem,
    settings_for_weights,
)
from splitter_mpc.core.ocp import MpcWeights
from splitter_mpc.core.solvers import SOLVERS, SolverOptions, make_backend

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
