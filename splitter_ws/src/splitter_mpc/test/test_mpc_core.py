"""The MPC core against physics and the hardware: limits, model, cost, plans."""

from __future__ import annotations

from dataclasses import replace

import casadi as ca
import numpy as np
import pytest

from splitter_model.model import PAPER_INITIAL_RADII_M, RobotModel, principal_inertia
from splitter_model.reachable import radius_squared_matrix
from splitter_mpc.core.controller import ControllerConfig
from splitter_mpc.core.gait import quaternion_multiply, rotation_matrix
from splitter_mpc.core.limits import (
    limb_radial_speed_max_m_s,
    morphing_limits,
    project_to_reachable,
)
from splitter_mpc.core.mpc import (
    InertialMorphingMpc,
    MpcSettings,
    PlanRequest,
    settings_for_weights,
)
from splitter_mpc.core.ocp import NU, MpcWeights, StateLayout, build_ocp, dynamics_function
from splitter_mpc.core.solvers import OBJECTIVE_SCALE_MIN, SolverOptions, fatrop_structure

MODEL = RobotModel()
DT = 0.01  # [s]
LIMITS = morphing_limits(MODEL, DT)
I0 = principal_inertia(MODEL, PAPER_INITIAL_RADII_M)  # [0.48, 141.36, 141.36]
W0 = np.array([-0.3, -0.9, 0.9])  # [rad/s] paper Table I
IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])
NX = StateLayout(attitude=True).nx  # [w, q, s]


@pytest.fixture(scope="module")
def mpc() -> InertialMorphingMpc:
    # the back-end in this process: these tests look into it (objective scale, solves)
    options = SolverOptions(compile=False, max_time_s=10.0, isolated=False)
    return InertialMorphingMpc(MODEL, MpcSettings(dt_s=0.05, integrator="rk4", options=options))


def test_squared_radii_are_linear_in_the_principal_moments() -> None:
    rng = np.random.default_rng(1)
    radii = rng.uniform(MODEL.radii_min_m, MODEL.radii_max_m, size=(20, 3))
    a = radius_squared_matrix(MODEL)
    np.testing.assert_allclose(principal_inertia(MODEL, radii) @ a.T, radii**2, rtol=1e-12)


def test_limits_are_the_hardware_ones() -> None:
    # Tether = 2 r_x: r_x moves at half the reel speed.
    assert LIMITS.radius_rate_max_m_s[0] == pytest.approx(MODEL.tether_speed_max_m_s / 2.0)
    # Limb: the knee at full speed at the stretched end of its range, where the tip
    # moves slowest per radian (finite difference of the reach).
    knee, h = MODEL.knee_min_rad, 1e-7
    dreach_dknee = (MODEL.limb_reach_m(knee) - MODEL.limb_reach_m(knee + h)) / h
    expected = dreach_dknee * MODEL.joint_speed_max_rad_s
    assert limb_radial_speed_max_m_s(MODEL) == pytest.approx(expected, rel=1e-4)
    np.testing.assert_allclose(
        LIMITS.inertia_max_kg_m2, principal_inertia(MODEL, MODEL.radii_max_m)
    )
    np.testing.assert_allclose(
        LIMITS.inertia_min_kg_m2, principal_inertia(MODEL, MODEL.radii_min_m)
    )
    assert np.all(LIMITS.inertia_min_kg_m2 > 0.0)
    # dI_max: the largest one-step change with every radius at its maximum moving at
    # its top speed (derivative along the corners of the step box, eq. 2 differentiated).
    r, eps = MODEL.radii_max_m, 1e-6
    corners = np.array(np.meshgrid(*[[-1.0, 1.0]] * 3)).reshape(3, -1).T
    moved = principal_inertia(MODEL, r + eps * corners * LIMITS.radius_step_max_m)
    rates = (moved - principal_inertia(MODEL, r)) / eps
    np.testing.assert_allclose(
        np.max(np.abs(rates), axis=0), LIMITS.inertia_step_max_kg_m2, rtol=1e-5
    )
    assert LIMITS.is_reachable(I0)
    assert not LIMITS.is_reachable([5.0, 141.0, 141.0])  # violates a triangle inequality


def test_projection_keeps_reachable_moments_and_clips_others() -> None:
    np.testing.assert_allclose(project_to_reachable(LIMITS, I0), I0, rtol=1e-12)
    clipped = project_to_reachable(LIMITS, principal_inertia(MODEL, [3.5, 0.2, 0.2]))
    np.testing.assert_allclose(np.sqrt(LIMITS.radii_squared(clipped))[0], 3.0)


def test_model_step_is_eulers_equation_with_the_correct_sign() -> None:
    """I_{k+1} w_{k+1} = I_k w_k - dt w_k x (I_k w_k) for any inertia step."""
    f = dynamics_function(DT, np.linalg.inv(LIMITS.radius_squared_matrix))
    s0 = LIMITS.radii_squared(I0)
    ds = np.array([-0.01, 0.002, -0.001])  # [m^2]
    x = np.concatenate([W0, IDENTITY, s0])
    x_next = np.asarray(f(x, np.concatenate([ds, [0.0]])), dtype=float).ravel()
    inertia_next = np.linalg.solve(LIMITS.radius_squared_matrix, s0 + ds)
    momentum = I0 * W0
    np.testing.assert_allclose(
        inertia_next * x_next[0:3], momentum - DT * np.cross(W0, momentum), rtol=1e-12
    )
    q_expected = IDENTITY + 0.5 * DT * quaternion_multiply(IDENTITY, np.concatenate([[0.0], W0]))
    np.testing.assert_allclose(x_next[3:7], q_expected / np.linalg.norm(q_expected), rtol=1e-12)


def test_model_conserves_world_angular_momentum_in_free_flight(mpc) -> None:
    """The minus sign conserves H = R I w (to Euler's O(dt)); the paper's plus does not."""
    x0 = mpc.ocp.state_from_measurement(W0, IDENTITY, I0)
    states = mpc.rollout(x0, np.zeros((300, NU)))  # 3 s, constant inertia
    world_h = np.array([rotation_matrix(x[3:7]) @ (I0 * x[0:3]) for x in states])
    drift = np.max(np.linalg.norm(world_h - world_h[0], axis=1)) / np.linalg.norm(world_h[0])
    assert drift < 5e-3
    body_h = I0 * states[:, 0:3]
    assert np.max(np.abs(body_h - body_h[0])) > 1.0  # the body-frame H does turn
    # The paper's printed sign, same integrator: H is not conserved.
    w, q = W0.copy(), IDENTITY.copy()
    flipped = []
    for _ in range(300):
        flipped.append(rotation_matrix(q) @ (I0 * w))
        q_dot = 0.5 * quaternion_multiply(q, np.concatenate([[0.0], w]))
        w = (I0 * w + DT * np.cross(w, I0 * w)) / I0
        q = (q + DT * q_dot) / np.linalg.norm(q + DT * q_dot)
    flipped = np.array(flipped)
    flipped_drift = np.max(np.linalg.norm(flipped - flipped[0], axis=1)) / np.linalg.norm(
        flipped[0]
    )
    assert flipped_drift > 10 * drift


def test_attitude_cost_treats_q_and_minus_q_alike() -> None:
    ocp = build_ocp(4, DT, LIMITS)
    cost = ca.Function("J", [ocp.z, ocp.p], [ocp.objective])
    rng = np.random.default_rng(2)
    xs = np.zeros((5, NX))
    xs[:, 0:3] = rng.normal(size=(5, 3))
    q = rng.normal(size=(5, 4))
    xs[:, 3:7] = q / np.linalg.norm(q, axis=1, keepdims=True)
    xs[:, 7:10] = LIMITS.radii_squared(I0)
    us = np.zeros((4, NU))
    q_ref = rng.normal(size=(5, 4))
    q_ref /= np.linalg.norm(q_ref, axis=1, keepdims=True)
    weights = MpcWeights(q_w=(0.0,) * 3, q_t=(0.0,) * 3, q_q=7.0, q_tq=3.0)
    from splitter_mpc.core.ocp import parameter_vector

    p = parameter_vector(ocp.layout, [0.0, 1.0, 0.0], q_ref, weights, I0)
    flipped = xs.copy()
    flipped[:, 3:7] *= -1.0
    j = float(cost(ocp.join(xs, us), p))
    assert j == pytest.approx(float(cost(ocp.join(flipped, us), p)), rel=1e-12)
    dots = np.sum(q_ref * xs[:, 3:7], axis=1)
    expected = 7.0 * 0.5 * np.sum(1.0 - dots[:4] ** 2) + 3.0 * 0.5 * (1.0 - dots[4] ** 2)
    assert j == pytest.approx(expected, rel=1e-9)


def test_plan_stays_within_what_the_hardware_reaches(mpc) -> None:
    mpc.reset()
    state = np.concatenate([W0, IDENTITY, I0])
    plan = mpc.solve(PlanRequest(0, state, [0, 1, 0], np.tile(IDENTITY, (51, 1)), MpcWeights()))
    assert plan.result.converged and plan.result.usable
    tol = 1e-6
    assert np.all(plan.radii >= MODEL.radii_min_m - tol)
    assert np.all(plan.radii <= MODEL.radii_max_m + tol)
    lim = mpc.limits  # per prediction step (50 ms)
    assert np.all(np.abs(np.diff(plan.radii, axis=0)) <= lim.radius_step_max_m + tol)
    assert np.all(np.abs(np.diff(plan.inertia, axis=0)) <= lim.inertia_step_max_kg_m2 + tol)
    np.testing.assert_allclose(plan.inertia[0], I0, rtol=1e-9)
    # the plan acts: it changes the inertia and lowers |w - w_ref| over the horizon
    assert np.max(np.abs(plan.inertia - I0)) > 0.1
    err = np.linalg.norm(plan.angular_velocity - [0.0, 1.0, 0.0], axis=1)
    assert err[-1] < err[0]
    # setpoint playback: the value at the end of each prediction step (or control tick)
    np.testing.assert_allclose(plan.setpoint_at(0), plan.inertia[1])
    np.testing.assert_allclose(plan.setpoint_at(135_000_000), plan.inertia[3])
    np.testing.assert_allclose(
        plan.setpoint_at(135_000_000, 10_000_000), 0.2 * plan.inertia[2] + 0.8 * plan.inertia[3]
    )
    np.testing.assert_allclose(plan.setpoint_at(10**10), plan.inertia[-1])


def test_warm_start_is_the_shifted_previous_solution(mpc) -> None:
    mpc.reset()
    x = np.concatenate([W0, IDENTITY, I0])
    first = mpc.solve(PlanRequest(0, x, [0, 1, 0], np.tile(IDENTITY, (51, 1)), MpcWeights()))
    measured = np.concatenate([first.angular_velocity[2], first.orientation[2], first.inertia[2]])
    x0 = mpc.ocp.state_from_measurement(measured[0:3], measured[3:7], measured[7:10])
    z0, lam_g, _ = mpc._warm_start(100_000_000, x0)
    xs, us = mpc.ocp.split(z0)
    old_xs, old_us = mpc.ocp.split(first.result.z)
    np.testing.assert_allclose(
        xs[:49], old_xs[2:], atol=1e-7
    )  # x_0 clipped to bounds  # 100 ms = 2 steps of 50 ms
    np.testing.assert_allclose(us[:48], old_us[2:], atol=1e-12)
    np.testing.assert_allclose(us[48:], 0.0)
    np.testing.assert_allclose(xs[49:], mpc.rollout(xs[48], us[48:])[1:], atol=1e-12)
    assert lam_g.shape == (mpc.ocp.n_g,)
    # a solve from there converges, from the warm start
    second = mpc.solve(
        PlanRequest(100_000_000, measured, [0, 1, 0], np.tile(IDENTITY, (51, 1)), MpcWeights())
    )
    assert second.result.converged


def test_rk4_model_conserves_the_body_momentum_norm_while_morphing() -> None:
    """|I w| is invariant under d/dt(I w) = -w x (I w) for any inertia history (RK4: O(dt^5))."""
    f = dynamics_function(0.05, np.linalg.inv(LIMITS.radius_squared_matrix), "rk4")
    x = np.concatenate([W0, IDENTITY, LIMITS.radii_squared(I0)])
    h0 = np.linalg.norm(I0 * W0)
    ds = np.array([-0.05, 0.004, -0.003])  # [m^2] per step
    for _ in range(40):
        x = np.asarray(f(x, np.concatenate([ds, [0.0]])), dtype=float).ravel()
    inertia = np.linalg.solve(LIMITS.radius_squared_matrix, x[7:10])
    assert np.linalg.norm(inertia * x[0:3]) == pytest.approx(h0, rel=1e-5)


def test_momentum_objective_weighs_the_rate_across_the_axis_and_the_reachable_spin() -> None:
    """The paper's J_w drops when the inertia grows (w = H / I). The momentum objective
    weighs the body rate across e (x, z here), the body momentum along e (unchanged by
    the inertia) and the spin rate |H| / Iyy against the reachable one."""
    ocp = build_ocp(4, 0.05, morphing_limits(MODEL, 0.05), integrator="rk4")
    from splitter_mpc.core.ocp import parameter_vector

    cost = ca.Function("J", [ocp.z, ocp.p], [ocp.objective])
    h = I0 * W0
    h_norm = float(np.linalg.norm(h))
    lim = ocp.limits
    costs = {}
    for objective in ("paper", "momentum"):
        weights = MpcWeights(objective=objective)
        p = parameter_vector(
            ocp.layout,
            [0, 1, 0],
            np.tile(IDENTITY, (5, 1)),
            weights,
            I0,
            momentum_norm=h_norm,
            axis_inertia_range_kg_m2=(4.57, 162.95),
        )
        for label, inertia in (("nominal", I0), ("inflated", I0 * [3.0, 1.1, 1.1])):
            xs = np.zeros((5, NX))
            xs[:, 0:3] = h / inertia  # the same body momentum in both configurations
            xs[:, 3:7] = IDENTITY
            xs[:, 7:10] = lim.radii_squared(inertia)
            costs[objective, label] = float(cost(ocp.join(xs, np.zeros((4, NU))), p))
    assert costs["paper", "inflated"] < 0.9 * costs["paper", "nominal"]

    # momentum objective: 4 stages + the end (Q_w = Q_t = 100 across e) on the body rate
    # across e; along e the momentum term is unchanged; the spin-rate term (|H| / Iyy
    # toward the reachable 1.10 rad/s) has Q_w,y = 100 per stage and Q_t,y = 10 at the end
    def across(inertia) -> float:
        return 5 * 100.0 * ((h[0] / inertia[0]) ** 2 + (h[2] / inertia[2]) ** 2)

    spin = lambda i_yy: 100.0 * (h_norm / i_yy - h_norm / 162.95) ** 2  # noqa: E731
    inflated = I0 * [3.0, 1.1, 1.1]
    change = spin(inflated[1]) - spin(I0[1])
    assert costs["momentum", "inflated"] - costs["momentum", "nominal"] == pytest.approx(
        across(inflated) - across(I0) + 4 * change + 10.0 / 100.0 * change, rel=1e-6
    )


def test_without_attitude_tracking_the_ocp_drops_q_and_keeps_the_optimum(mpc) -> None:
    """q feeds neither the rate dynamics nor a cost when Q_q = Q_tq = 0: leaving it out
    of the state (6 states, not 10) must not change the planned rates or inertia."""
    lean = InertialMorphingMpc(MODEL, replace(mpc.settings, attitude_states=False))
    assert lean.ocp.state.nx == 6 and lean.ocp.n_z < mpc.ocp.n_z
    mpc.reset()
    x = np.concatenate([W0, IDENTITY, I0])
    refs = np.tile(IDENTITY, (51, 1))
    for weights in (MpcWeights(), MpcWeights(objective="momentum")):
        full = mpc.solve(PlanRequest(0, x, [0, 1, 0], refs, weights))
        mpc.reset()
        plan = lean.solve(PlanRequest(0, x, [0, 1, 0], refs, weights))
        lean.reset()
        assert full.result.converged and plan.result.converged
        assert plan.orientation is None and full.orientation is not None
        np.testing.assert_allclose(plan.angular_velocity, full.angular_velocity, atol=1e-6)
        np.testing.assert_allclose(plan.inertia, full.inertia, rtol=1e-6, atol=1e-6)
        assert plan.result.cost == pytest.approx(full.result.cost, rel=1e-6)


def test_attitude_weights_need_the_attitude_in_the_state() -> None:
    tracking = MpcWeights(q_q=10.0)
    lean = MpcSettings(attitude_states=False, options=SolverOptions(compile=False))
    assert settings_for_weights(lean, tracking).attitude_states
    assert not settings_for_weights(MpcSettings(), MpcWeights()).attitude_states
    with pytest.raises(ValueError, match="attitude_states"):
        ControllerConfig(weights=tracking, mpc=lean)
    mpc = InertialMorphingMpc(MODEL, lean)
    state = np.concatenate([W0, IDENTITY, I0])
    with pytest.raises(ValueError, match="attitude"):
        mpc.solve(PlanRequest(0, state, [0, 1, 0], np.tile(IDENTITY, (51, 1)), tracking))
    with pytest.raises(ValueError, match="no attitude"):
        _ = mpc.ocp.state.q


def test_weights_per_stage_keep_one_continuous_time_cost() -> None:
    """The same flight (rate error held, inertia moving at a constant rate, 0.4 s) costs
    the same on 8 steps of 50 ms with the weights as given and on 4 steps of 100 ms
    with ``per_stage(2)``: running terms grow with the step, R (on dI per step) falls."""
    from splitter_mpc.core.ocp import parameter_vector

    weights = MpcWeights(q_w=(100.0, 30.0, 100.0), r=(0.01, 1.0, 2.0), q_t=(7.0, 7.0, 7.0))
    s_rate = np.array([-0.5, 0.05, -0.02])  # [m^2/s] constant radius-squared rate
    w = np.array([0.3, 0.8, -0.2])  # [rad/s] held
    costs = []
    for steps, dt, stage_weights in ((8, 0.05, weights), (4, 0.1, weights.per_stage(2.0))):
        ocp = build_ocp(steps, dt, morphing_limits(MODEL, dt), attitude=False)
        cost = ca.Function("J", [ocp.z, ocp.p], [ocp.objective])
        t = dt * np.arange(steps + 1)[:, None]
        xs = np.hstack([np.tile(w, (steps + 1, 1)), LIMITS.radii_squared(I0) + s_rate * t])
        us = np.hstack([np.tile(s_rate * dt, (steps, 1)), np.zeros((steps, 1))])
        refs = np.tile(IDENTITY, (steps + 1, 1))
        p = parameter_vector(ocp.layout, [0.0, 1.0, 0.0], refs, stage_weights, I0)
        costs.append(float(cost(ocp.join(xs, us), p)))
    assert costs[1] == pytest.approx(costs[0], rel=1e-12)
    # the terminal weights are not running ones; a step as given changes nothing
    assert weights.per_stage(2.0).q_t == weights.q_t
    assert weights.per_stage(1.0) is weights
    with pytest.raises(ValueError, match="step_ratio"):
        weights.per_stage(0.0)
    assert MpcSettings(dt_s=0.1, weights_step_s=0.05).weights_step_ratio == pytest.approx(2.0)
    assert MpcSettings(dt_s=0.1).weights_step_ratio == 1.0
    with pytest.raises(ValueError, match="weights_step_s"):
        MpcSettings(weights_step_s=-0.05)


def scaled_weights(weights: MpcWeights, factor: float) -> MpcWeights:
    return replace(
        weights,
        q_w=tuple(factor * v for v in weights.q_w),
        r=tuple(factor * v for v in weights.r),
        q_t=tuple(factor * v for v in weights.q_t),
        tension_slack=factor * weights.tension_slack,
    )


def test_objective_scaling_makes_a_solve_independent_of_the_weights_scale(mpc) -> None:
    """c J has the optimum of J; scaled as IPOPT does (largest gradient at the warm start to
    100), both are one scaled problem, so fatrop takes the same steps (it has no scaling of
    its own: unscaled, a 8x heavier cost changes its barrier path and stopping test)."""
    x = np.concatenate([W0, IDENTITY, I0])
    q_ref = np.tile(IDENTITY, (51, 1))
    plans = []
    for factor in (1.0, 8.0):
        mpc.reset()
        weights = scaled_weights(MpcWeights(), factor)
        request = PlanRequest(0, x, [0, 1, 0], q_ref, weights)
        gradient_scale = mpc.backend.objective_scale(mpc.problem(request))
        assert gradient_scale < 1.0  # Table I's gradient is ~500: scaled down to 100
        plans.append(mpc.solve(request))
    one, eight = plans
    assert one.result.converged and eight.result.converged
    assert one.result.iterations == eight.result.iterations
    np.testing.assert_allclose(eight.result.cost, 8.0 * one.result.cost, rtol=1e-9)
    np.testing.assert_allclose(eight.inertia, one.inertia, rtol=1e-9, atol=1e-9)


def test_a_wild_start_is_not_scaled_below_ipopts_minimum(mpc) -> None:
    mpc.reset()
    x = np.concatenate([W0, IDENTITY, I0])
    weights = scaled_weights(MpcWeights(), 2.0**40)  # gradient ~5e14
    data = mpc.problem(PlanRequest(0, x, [0, 1, 0], np.tile(IDENTITY, (51, 1)), weights))
    assert mpc.backend.objective_scale(data) == OBJECTIVE_SCALE_MIN


def test_fatrops_tuning_options_reach_it_and_are_checked() -> None:
    """mu_init and bound_push go to fatrop: the same cold problem takes other iterations;
    the defaults are fatrop's own (the same iterations as without them)."""
    state = np.concatenate([W0, IDENTITY, I0])
    request = PlanRequest(0, state, [0, 1, 0], np.tile(IDENTITY, (51, 1)), MpcWeights())
    iterations = {}
    for mu_init in (0.1, 1e-3):
        options = SolverOptions(compile=False, isolated=False, fatrop_mu_init=mu_init)
        settings = MpcSettings(dt_s=0.05, integrator="rk4", options=options)
        with InertialMorphingMpc(MODEL, settings) as mpc:
            plan = mpc.solve(request)
        assert plan.result.converged
        iterations[mu_init] = plan.result.iterations
    assert iterations[0.1] != iterations[1e-3]
    # the defaults are fatrop's own: given or not, the solve is the same to the last bit
    with InertialMorphingMpc(MODEL, settings) as mpc:
        data, ocp = mpc.problem(request), mpc.ocp
    defaults = SolverOptions()
    nlp = {"x": ocp.z, "p": ocp.p, "f": ocp.objective, "g": ocp.g}
    common = {**fatrop_structure(ocp), "expand": True, "print_time": False, "fatrop.print_level": 0}
    tuned = {
        "fatrop.mu_init": defaults.fatrop_mu_init,
        "fatrop.bound_push": defaults.fatrop_bound_push,
    }
    solutions = [
        np.asarray(
            ca.nlpsol("s", "fatrop", nlp, opts)(
                x0=data.z0, p=data.p, lbx=data.lbz, ubx=data.ubz, lbg=data.lbg, ubg=data.ubg
            )["x"]
        )
        for opts in (common, {**common, **tuned})
    ]
    np.testing.assert_array_equal(solutions[0], solutions[1])
    for field in ("fatrop_mu_init", "fatrop_bound_push"):
        for bad in (0.0, -1.0, float("nan")):
            with pytest.raises(ValueError, match=field):
                SolverOptions(**{field: bad})


def test_a_lazy_back_end_is_built_at_the_first_solve_and_solves_alike(mpc) -> None:
    state = np.concatenate([W0, IDENTITY, I0])
    request = PlanRequest(0, state, [0, 1, 0], np.tile(IDENTITY, (51, 1)), MpcWeights())
    with InertialMorphingMpc(MODEL, mpc.settings, lazy_backend=True) as lazy:
        assert lazy.backend is None and lazy.deadline_misses == 0
        lazy.close()  # nothing to stop yet
        plan = lazy.solve(request)
        assert lazy.backend is not None
    mpc.reset()
    expected = mpc.solve(request)
    np.testing.assert_array_equal(plan.result.z, expected.result.z)
