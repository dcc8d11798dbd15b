"""The MPC scheduler: re-plan grid, playback, phases, failures, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from splitter_model.model import (
    PAPER_INITIAL_RADII_M,
    RobotModel,
    principal_inertia,
    radii_from_inertia,
)
from splitter_mpc.core.controller import ControllerConfig, MorphingController
from splitter_mpc.core.mpc import InertialMorphingMpc, MpcSettings
from splitter_mpc.core.solvers import SolverOptions

MODEL = RobotModel()
MS = 1_000_000  # [ns]
I0 = principal_inertia(MODEL, PAPER_INITIAL_RADII_M)
W0 = np.array([-0.3, -0.9, 0.9])  # [rad/s]
Q0 = np.array([1.0, 0.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def mpc() -> InertialMorphingMpc:
    # no wall-time deadline: a loaded CI machine must not turn solves late
    return InertialMorphingMpc(
        MODEL,
        MpcSettings(
            dt_s=0.05, integrator="rk4", options=SolverOptions(compile=False, max_time_s=10.0)
        ),
    )


def controller(mpc: InertialMorphingMpc, **config) -> MorphingController:
    mpc.reset()
    ctl = MorphingController(MODEL, ControllerConfig(mpc=mpc.settings, **config), mpc)
    ctl.set_reference(0, [0.0, 1.0, 0.0], Q0)
    return ctl


def tick(ctl: MorphingController, t_ms: int, phase: str | None = "IN_FLIGHT") -> np.ndarray:
    return ctl.on_state(t_ms * MS, W0, Q0, I0, phase)


def test_replans_on_the_100_ms_grid_and_plays_the_plan_back(mpc) -> None:
    ctl = controller(mpc)
    first = tick(ctl, 0)
    assert ctl.status.replanned and ctl.status.solve_ok and ctl.status.active
    plan = ctl.plan
    assert plan.dt_ns == 50 * MS  # the long-horizon option's prediction step
    # each 10 ms tick commands the plan's inertia at the end of the tick (linear in a step)
    np.testing.assert_allclose(first, 0.8 * plan.inertia[0] + 0.2 * plan.inertia[1])
    for t_ms in range(10, 100, 10):
        setpoint = tick(ctl, t_ms)
        assert not ctl.status.replanned
        j, share = divmod(t_ms + 10, 50)
        expected = (1 - share / 50) * plan.inertia[j] + share / 50 * plan.inertia[j + 1]
        np.testing.assert_allclose(setpoint, expected)
    tick(ctl, 100)
    assert ctl.status.replanned and ctl.plan is not plan and ctl.status.solves == 2


def test_injected_failure_keeps_executing_the_previous_plan_then_recovers(mpc) -> None:
    ctl = controller(mpc)
    tick(ctl, 0)
    plan = ctl.plan
    ctl.inject_solver_failures(1)
    for t_ms in range(100, 200, 10):
        setpoint = tick(ctl, t_ms)
        np.testing.assert_allclose(setpoint, plan.setpoint_at(t_ms * MS, 10 * MS))  # the old plan
    assert ctl.status.failures == 1 and ctl.status.consecutive_failures == 1
    assert ctl.status.solve_status == "injected_failure" and not ctl.status.solve_ok
    assert ctl.plan is plan and ctl.status.plan_age_s == pytest.approx(0.19)
    tick(ctl, 200)
    assert ctl.status.solve_ok and ctl.status.consecutive_failures == 0 and ctl.plan is not plan


def test_a_solver_exception_is_a_failed_solve_and_never_a_nan(mpc, monkeypatch) -> None:
    ctl = controller(mpc)

    def broken(*args, **kwargs):
        raise RuntimeError("solver crashed")

    monkeypatch.setattr(ctl.mpc, "solve", broken)
    setpoint = tick(ctl, 0)
    np.testing.assert_allclose(setpoint, I0)  # no plan yet: hold the measured inertia
    assert ctl.status.solve_status.startswith("error: solver crashed")
    assert ctl.status.failures == 1


def test_inactive_when_disabled_landed_or_without_reference(mpc) -> None:
    ctl = controller(mpc, enabled=False)
    first = ctl.on_state(0, W0, Q0, I0, "IN_FLIGHT")
    later = ctl.on_state(10 * MS, W0, Q0, 1.1 * I0, "IN_FLIGHT")
    np.testing.assert_allclose(first, I0)
    np.testing.assert_allclose(later, I0)  # the nominal (first measured) inertia is held
    assert not ctl.status.active and ctl.status.solves == 0

    ctl = controller(mpc)
    tick(ctl, 0, "IN_FLIGHT")
    assert ctl.status.active
    before = tick(ctl, 10, "IN_FLIGHT")
    assert not np.allclose(before, I0)  # the plan morphs
    # On the ground (LAUNCH, JUMP) the legs stand in the nominal shape: I0 measured first.
    np.testing.assert_allclose(tick(ctl, 20, "JUMP"), I0)
    assert not ctl.status.active and ctl.plan is None
    tick(ctl, 30, "IN_FLIGHT")  # active again in flight: re-plans at once
    assert ctl.status.active and ctl.status.replanned
    flying = tick(ctl, 40, "IN_FLIGHT")
    # LANDED keeps the shape the robot landed in: the last setpoint, not the nominal.
    np.testing.assert_allclose(tick(ctl, 50, "LANDED"), flying)
    np.testing.assert_allclose(tick(ctl, 60, "LANDED"), flying)
    assert not ctl.status.active and ctl.plan is None

    mpc.reset()
    fresh = MorphingController(MODEL, ControllerConfig(), mpc)
    np.testing.assert_allclose(fresh.on_state(0, W0, Q0, I0, None), I0)
    assert not fresh.status.active  # no attitude reference yet


def test_the_limbs_go_back_to_the_legs_before_a_predicted_touchdown(mpc) -> None:
    """In flight with the stance shape asked for (touchdown within the gait's lead), the
    controller hands the limbs back and holds the tether measured at the hand-back, in
    the air and on the ground; after the next lift-off it morphs again."""
    ctl = controller(mpc)
    tick(ctl, 0, "IN_FLIGHT")
    assert not np.allclose(tick(ctl, 10, "IN_FLIGHT"), I0)  # morphing in flight
    # From a morphed shape: the nominal limbs and the tether measured at the hand-back.
    nominal = principal_inertia(MODEL, radii_from_inertia(MODEL, I0))
    morphed_radii = radii_from_inertia(MODEL, I0) * np.array([1.05, 1.4, 0.7])
    morphed = principal_inertia(MODEL, morphed_radii)
    expected = principal_inertia(MODEL, [morphed_radii[0], *radii_from_inertia(MODEL, nominal)[1:]])
    handed_back = ctl.on_state(20 * MS, W0, Q0, morphed, "IN_FLIGHT", stance_shape=True)
    np.testing.assert_allclose(handed_back, expected, rtol=1e-12)
    assert not ctl.status.active and ctl.plan is None
    # Held while the reel still moves, through the landing and on the ground before a jump
    # (a setpoint that followed the measured tether kept a moving reel moving).
    for t_ms, phase in ((25, "LANDING"), (30, "JUMP"), (35, "JUMP")):
        held = ctl.on_state(t_ms * MS, W0, Q0, I0, phase, stance_shape=True)
        np.testing.assert_allclose(held, expected, rtol=1e-12)
    ctl.on_state(40 * MS, W0, Q0, I0, "IN_FLIGHT", stance_shape=False)
    assert ctl.status.active and ctl.status.replanned
    # The next hand-back takes the tether measured then.
    handed_back = ctl.on_state(45 * MS, W0, Q0, I0, "IN_FLIGHT", stance_shape=True)
    np.testing.assert_allclose(handed_back, nominal, rtol=1e-12)


def test_bad_input_is_rejected_and_leaves_the_state_unchanged(mpc) -> None:
    ctl = controller(mpc)
    tick(ctl, 0)
    plan = ctl.plan
    for w, q, inertia in (
        ([np.nan, 0.0, 0.0], Q0, I0),
        (W0, [0.0, 0.0, 0.0, 0.0], I0),
        (W0, Q0, [0.5, -1.0, 1.0]),
        (W0, Q0, [1.0, 2.0]),
    ):
        with pytest.raises(ValueError):
            ctl.on_state(10 * MS, w, q, inertia, "IN_FLIGHT")
    assert ctl.plan is plan
    with pytest.raises(ValueError):
        ctl.set_reference(0, [0.0, np.inf, 0.0], Q0)


def test_config_rejects_inconsistent_periods() -> None:
    with pytest.raises(ValueError, match="multiple"):
        ControllerConfig(replan_period_s=0.015)
    with pytest.raises(ValueError, match="multiple"):  # 100 ms is not a whole number of steps
        ControllerConfig(mpc=MpcSettings(dt_s=0.03))
    assert ControllerConfig().mpc.dt_s == 0.01 and ControllerConfig().weights.objective == "paper"
    with pytest.raises(ValueError, match="nominal"):
        ControllerConfig(nominal_inertia_kg_m2=(1.0, -1.0, 1.0))


@pytest.mark.parametrize(
    ("isolated", "status", "misses"), [(False, "late", 0), (True, "deadline_missed", 1)]
)
def test_a_late_solve_is_not_executed(isolated: bool, status: str, misses: int) -> None:
    options = SolverOptions(compile=False, max_time_s=1e-6, isolated=isolated)
    with InertialMorphingMpc(MODEL, MpcSettings(options=options)) as late_mpc:
        ctl = MorphingController(MODEL, ControllerConfig(), late_mpc)
        ctl.set_reference(0, [0.0, 1.0, 0.0], Q0)
        np.testing.assert_allclose(tick(ctl, 0), I0)  # no plan: hold the measured inertia
    # in this process the solve ends and is found late; isolated, it is abandoned
    assert ctl.status.solve_status.startswith(status) and not ctl.status.solve_ok
    assert ctl.plan is None and ctl.status.failures == 1
    assert ctl.status.deadline_misses == misses


def test_recovery_asks_for_the_recovery_spin_until_the_body_has_turned(mpc, monkeypatch) -> None:
    """Hysteresis on the rate across the reference axis: in above 0.05, out under 0.005."""
    given = []
    solve = mpc.solve

    def recording_solve(request):
        given.append(np.array(request.w_ref_rad_s, dtype=float))
        return solve(request)

    monkeypatch.setattr(mpc, "solve", recording_solve)
    ctl = controller(mpc, recovery_spin_rad_s=2.0)
    rates = [  # [rad/s] body rate, the rate across y it has
        W0,  # 0.95: in
        np.array([0.02, 1.0, 0.0]),  # 0.02: still in
        np.array([0.003, 1.0, -0.002]),  # 0.0036: out
        np.array([0.02, 1.0, 0.0]),  # 0.02: still out
        np.array([0.0, 1.0, 0.08]),  # 0.08: in again
    ]
    recovering = []
    for k, w in enumerate(rates):
        ctl.on_state(k * 100 * MS, w, Q0, I0, "IN_FLIGHT")
        assert ctl.status.replanned
        recovering.append(ctl.status.recovering)
    assert recovering == [True, True, False, False, True]
    expected = [[0.0, 2.0, 0.0] if r else [0.0, 1.0, 0.0] for r in recovering]
    np.testing.assert_array_equal(np.array(given), expected)
    # off by default; a reference faster than the recovery spin is never slowed down
    plain = controller(mpc)
    plain.on_state(0, W0, Q0, I0, "IN_FLIGHT")
    assert not plain.status.recovering
    np.testing.assert_array_equal(given[-1], [0.0, 1.0, 0.0])
    fast = controller(mpc, recovery_spin_rad_s=0.5)
    fast.on_state(0, W0, Q0, I0, "IN_FLIGHT")
    assert fast.status.recovering
    np.testing.assert_array_equal(given[-1], [0.0, 1.0, 0.0])


def test_recovery_only_for_a_tumble_too_slow_for_the_reference(mpc) -> None:
    """The momentum gate: |H| / I_y,max against |w_ref| (1 rad/s here)."""
    i_y_max = mpc.limits.inertia_max_kg_m2[1]  # [kg m^2] about the reference axis y
    paper = controller(mpc, recovery_spin_rad_s=2.0, recovery_momentum_ratio_max=1.0)
    paper.on_state(0, W0, Q0, I0, "IN_FLIGHT")  # Table I's tumble
    slowest = paper.slowest_spin_rad_s(W0, I0)
    assert slowest == pytest.approx(np.linalg.norm(I0 * W0) / i_y_max)
    assert slowest == pytest.approx(1.104, abs=1e-3)  # more momentum than 1 rad/s needs
    assert not paper.status.recovering
    slow_w = np.array([1.5, 0.1, 0.1])  # [rad/s] mostly about the tether: |H| = 20.0
    slow = controller(mpc, recovery_spin_rad_s=2.0, recovery_momentum_ratio_max=1.0)
    slow.on_state(0, slow_w, Q0, I0, "IN_FLIGHT")
    assert slow.slowest_spin_rad_s(slow_w, I0) < 0.2
    assert slow.status.recovering
    # a ratio above Table I's momentum lets it recover too
    loose = controller(mpc, recovery_spin_rad_s=2.0, recovery_momentum_ratio_max=1.2)
    loose.on_state(0, W0, Q0, I0, "IN_FLIGHT")
    assert loose.status.recovering


def test_config_rejects_bad_recovery_settings() -> None:
    with pytest.raises(ValueError, match="recovery_spin_rad_s"):
        ControllerConfig(recovery_spin_rad_s=-1.0)
    with pytest.raises(ValueError, match="recovery_enter_rate_rad_s"):
        ControllerConfig(recovery_enter_rate_rad_s=float("nan"))
    with pytest.raises(ValueError, match="recovery_exit_rate_rad_s must be <="):
        ControllerConfig(recovery_exit_rate_rad_s=0.1, recovery_enter_rate_rad_s=0.05)
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="recovery_momentum_ratio_max"):
            ControllerConfig(recovery_momentum_ratio_max=bad)


def test_after_a_fault_the_effort_weights_are_scaled_from_the_tick_the_bounds_apply(
    mpc, monkeypatch
) -> None:
    ctl = controller(mpc, fault_effort_scale=0.1)
    seen = []
    solve = mpc.solve
    monkeypatch.setattr(
        mpc, "solve", lambda request: seen.append(request.weights) or solve(request)
    )
    r = np.asarray(ctl.weights.r)
    tick(ctl, 0)
    lo = np.array([0.5, 0.15, MODEL.limb_radius_min_m])
    hi = np.array([3.0, 0.3, MODEL.limb_radius_max_m])
    ctl.set_radius_bounds(lo, hi, stamp_ns=50 * MS)  # found at 50 ms: applied from 60 ms
    for t_ms in range(10, 110, 10):
        tick(ctl, t_ms)
    np.testing.assert_array_equal(seen[0].r, r)  # before the fault
    np.testing.assert_allclose(seen[1].r, 0.1 * r)  # the re-plan at 100 ms
    assert seen[1].q_w == seen[0].q_w and ctl.weights.r == tuple(r)  # only R, and per solve
    ctl.set_radius_bounds(None, None)  # healthy again (a reset): the paper's R
    tick(ctl, 200)
    np.testing.assert_array_equal(seen[-1].r, r)


def test_config_rejects_a_fault_effort_scale_outside_its_range() -> None:
    for bad in (0.0, 1.5, float("nan")):
        with pytest.raises(ValueError, match="fault_effort_scale"):
            ControllerConfig(fault_effort_scale=bad)
