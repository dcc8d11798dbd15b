"""The MPC with a robot of other masses (an estimate): exact in scaled coordinates, shapes
out, a tick that waits for its masses, and setpoints taken the actuators' lag ahead."""

from __future__ import annotations

import numpy as np
import pytest

from splitter_model.model import PAPER_INITIAL_RADII_M, RobotModel, principal_inertia, with_masses
from splitter_model.reachable import inertia_map
from splitter_mpc.core.controller import ControllerConfig, MorphingController
from splitter_mpc.core.mpc import InertialMorphingMpc, MpcSettings
from splitter_mpc.core.mpc_tick import MpcTick, MpcTickSettings
from splitter_mpc.core.ocp import dynamics_function
from splitter_mpc.core.solvers import SolverOptions
from splitter_msgs_py import names

MODEL = RobotModel()
OTHER = with_masses(MODEL, (3.3, 1.35, 1.6))  # [kg] m_x, m_y, m_z
MS = 1_000_000  # [ns]
W0 = np.array([-0.3, -0.9, 0.9])  # [rad/s]
Q0 = np.array([1.0, 0.0, 0.0, 0.0])
DT_S = 0.05  # [s] prediction step


@pytest.fixture(scope="module")
def mpc() -> InertialMorphingMpc:
    settings = MpcSettings(
        dt_s=DT_S, integrator="rk4", options=SolverOptions(compile=False, max_time_s=10.0)
    )
    return InertialMorphingMpc(MODEL, settings)


def test_the_built_dynamics_in_scaled_radii_are_the_other_robots(mpc) -> None:
    mpc.set_mass_model(OTHER)
    d = mpc.column_scale
    np.testing.assert_allclose(inertia_map(OTHER), inertia_map(MODEL) * d[None, :], rtol=1e-14)
    layout = mpc.ocp.state
    built = dynamics_function(DT_S, inertia_map(MODEL), "rk4", layout)
    other = dynamics_function(DT_S, inertia_map(OTHER), "rk4", layout)
    rng = np.random.default_rng(0)
    for _ in range(5):
        x = np.concatenate([rng.normal(0, 1, 3), rng.uniform(0.04, 0.16, 3) * [50, 1, 1]])
        if layout.attitude:
            x = np.concatenate([x[:3], Q0, x[3:]])
        u = np.concatenate([rng.normal(0, 1e-3, 3), [0.0]])
        scaled_x, scaled_u = x.copy(), u.copy()
        scaled_x[layout.radii_sq] *= d
        scaled_u[:3] *= d
        expected = np.asarray(other(x, u)).ravel()
        got = np.asarray(built(scaled_x, scaled_u)).ravel()
        got[layout.radii_sq] /= d
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-14)
    mpc.set_mass_model(MODEL)
    np.testing.assert_array_equal(mpc.column_scale, np.ones(3))


@pytest.mark.parametrize(
    "hemi_inertia", [(0.0, 0.0, 0.0), (0.03, 0.045, 0.04)], ids=["point bodies", "hemi bodies"]
)
def test_a_plan_for_other_masses_comes_back_as_shapes(mpc, hemi_inertia) -> None:
    """Other masses, and hemi bodies with their own moments J [kg m^2]: the robot's
    inertia is eq. (2) of its masses plus 2 J, and the plan starts from its true shape."""
    mpc.reset()
    ctl = MorphingController(MODEL, ControllerConfig(mpc=mpc.settings), mpc)
    ctl.set_reference(0, [0.0, 1.0, 0.0], Q0)
    ctl.set_mass_model(OTHER, hemi_inertia)
    try:
        own = 2.0 * np.asarray(hemi_inertia)
        inertia = principal_inertia(OTHER, PAPER_INITIAL_RADII_M) + own  # what the robot has
        ctl.on_state(0, W0, Q0, inertia, "IN_FLIGHT")
        plan = ctl.plan
        assert plan is not None and plan.result.usable
        # the setpoints are the built model's moments of the planned radii: an allocator
        # with the nominal model turns them back into exactly those radii
        np.testing.assert_allclose(plan.inertia, principal_inertia(MODEL, plan.radii), rtol=1e-9)
        np.testing.assert_allclose(plan.radii[0], PAPER_INITIAL_RADII_M, rtol=1e-6)
        assert np.all(plan.radii <= MODEL.radii_max_m + 1e-6)
        assert np.all(plan.radii >= MODEL.radii_min_m - 1e-6)
    finally:
        mpc.set_mass_model(MODEL)


def test_a_tick_with_estimated_masses_waits_for_them(mpc) -> None:
    mpc.reset()
    ctl = MorphingController(MODEL, ControllerConfig(mpc=mpc.settings), mpc)
    tick = MpcTick(ctl, MpcTickSettings(estimated_masses=True))
    tick.set_reference(0, [0.0, 1.0, 0.0], Q0)
    inertia = principal_inertia(MODEL, PAPER_INITIAL_RADII_M)
    try:
        assert tick.on_state(0, W0, Q0, inertia) is None  # no masses for tick 0 yet
        assert tick.add(names.ESTIMATE_MASSES, 0, np.array([3.3, 1.35, 1.6])) is None
        hemi = np.array([0.03, 0.045, 0.04])  # [kg m^2] and the bodies' own moments
        answer = tick.add(names.ESTIMATE_HEMI_INERTIA, 0, hemi)
        assert answer is not None and answer.setpoint_kg_m2 is not None
        np.testing.assert_allclose(mpc.column_scale[1:], [1.35 / 1.5, 1.6 / 1.5])
        # the shapes' states carry D s + c with M_built c = 2 J
        np.testing.assert_allclose(mpc.ocp.inertia_map @ mpc.state_offset, 2.0 * hemi)
    finally:
        mpc.set_mass_model(MODEL)


def test_setpoints_are_taken_the_actuators_lag_ahead_on_the_plan(mpc) -> None:
    mpc.reset()
    ctl = MorphingController(MODEL, ControllerConfig(mpc=mpc.settings, actuator_lag_s=0.05), mpc)
    ctl.set_reference(0, [0.0, 1.0, 0.0], Q0)
    setpoint = ctl.on_state(0, W0, Q0, principal_inertia(MODEL, PAPER_INITIAL_RADII_M))
    np.testing.assert_allclose(setpoint, ctl.plan.setpoint_at(50 * MS, 10 * MS))
    with pytest.raises(ValueError, match="actuator_lag_s"):
        ControllerConfig(actuator_lag_s=-0.01)
