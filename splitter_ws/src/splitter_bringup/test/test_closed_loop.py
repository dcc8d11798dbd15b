"""The paper's flight scenarios in the library closed loop (simulator, allocator, gait, MPC).

Physics first: angular momentum is conserved in torque-free flight whatever the
controller does, so the MPC can only turn it into the body y axis (and the final
spin rate is |H| / Iyy). The paper's own numbers are compared where this
implementation reproduces them; where it does not, the tests state the physical
reason (explained in the splitter_mpc.core.mpc docstring).
For the same reason orientation tracking is measured against a reachable attitude
reference, body y along the conserved H (``attitude_reference: momentum_aligned``).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from splitter_bringup.analysis.metrics import attitude_reference_series, flight_summary
from splitter_bringup.run.library import controller_config, library_controller, run_closed_loop
from splitter_bringup.scenario.definition import load_scenario
from splitter_model.model import RobotModel
from splitter_mpc.core.controller import MorphingController
from splitter_mpc.core.gait import rotation_matrix
from splitter_mpc.core.mpc import MpcSettings
from splitter_mpc.core.solvers import SolverOptions

pytestmark = pytest.mark.slow
MODEL = RobotModel()
# SX virtual machine: no compiler and no cache needed; the same solutions.
MPC = MpcSettings(options=SolverOptions(compile=False, max_time_s=10.0))  # lockstep: no deadline


# Stored closed-loop runs (do-mpc style golden test). After an intended change of the
# simulator or the controller, rewrite them with
#   SPLITTER_UPDATE_GOLDEN=1 .venv/bin/pytest -k golden \
#       splitter_ws/src/splitter_bringup/test/test_closed_loop.py
# and say in the commit why the trajectories moved.
GOLDEN = Path(__file__).parent / "data" / "closed_loop_golden.npz"
GOLDEN_STEP_S = 0.1  # [s] samples stored per run
# Solves stop at a scaled optimality of 1e-6, so another CPU or libm may move a run
# by ~1e-6; real changes move it by far more (the open loop differs by ~1 rad/s).
# Measured: 1e-6 rad/s added to the initial rates moves these runs by <= 3e-5 rad/s
# and 2e-3 kg m^2. paper_mpc is left out: its closed loop turns that 1e-6 into
# 0.02 rad/s (its short horizon switches between plans), so it is checked by figures.
GOLDEN_RUNS = (
    ("spin_stabilization", "mpc"),
    ("spin_stabilization", "open_loop"),
    ("orientation_tracking", "quaternion_tracking"),
    ("orientation_tracking", "velocity_only"),
)
GOLDEN_ATOL = {
    "angular_velocity_rad_s": 2e-3,  # [rad/s]
    "orientation_wxyz": 2e-3,  # [-]
    "principal_inertia_kg_m2": 0.2,  # [kg m^2] of 0.5-163
    "radii_m": 2e-3,  # [m]
}


def run(name: str, variant: str, **kwargs):
    scenario = load_scenario(name, variant)
    series = run_closed_loop(scenario, mpc=MPC, **kwargs)
    metrics = flight_summary(
        series,
        scenario.paper,
        scenario.controller.w_ref_rad_s,
        scenario.controller.attitude_reference,
    )
    return series, {k: m.value for k, m in metrics.items()}


@pytest.fixture(scope="module")
def spin():
    return {v: run("spin_stabilization", v) for v in ("mpc", "paper_mpc", "open_loop")}


@pytest.fixture(scope="module")
def orientation():
    """variant -> (series, metrics, the MPC's controller: it holds the reference it was given)."""
    runs = {}
    for variant in ("quaternion_tracking", "velocity_only"):
        config = controller_config(load_scenario("orientation_tracking", variant), MPC)
        controller = MorphingController(MODEL, config)
        runs[variant] = (*run("orientation_tracking", variant, controller=controller), controller)
    return runs


def off_axis_rate(series) -> float:
    final = series.t_s >= series.t_s[-1] - 0.5
    w = series.angular_velocity_rad_s[final]
    return float(np.mean(np.hypot(w[:, 0], w[:, 2])))


def test_flight_conserves_angular_momentum_and_stays_reachable(spin) -> None:
    for series, metrics in spin.values():
        assert metrics["momentum_end"] == pytest.approx(metrics["momentum_start"], rel=1e-3)
        assert np.all(np.isfinite(series.inertia_setpoint_kg_m2))
        assert np.all(series.radii_m >= MODEL.radii_min_m - 1e-6)
        assert np.all(series.radii_m <= MODEL.radii_max_m + 1e-6)
    open_loop, metrics = spin["open_loop"]
    inertia = open_loop.principal_inertia_kg_m2
    assert np.max(np.abs(inertia - inertia[0])) < 1e-9
    # constant inertia, no torque: the rotational energy is conserved too
    assert metrics["energy_end_j"] == pytest.approx(metrics["energy_start_j"], rel=1e-6)


def test_mpc_turns_the_spin_toward_body_y_where_the_open_loop_tumbles(spin) -> None:
    mpc, mpc_metrics = spin["mpc"]
    open_loop, open_metrics = spin["open_loop"]
    # Open loop: the body is axisymmetric about x (Iyy = Izz): w_x and sqrt(w_y^2 + w_z^2)
    # stay constant while (w_y, w_z) precesses: it never settles about y.
    w = open_loop.angular_velocity_rad_s
    np.testing.assert_allclose(w[:, 0], -0.3, atol=1e-6)
    np.testing.assert_allclose(np.hypot(w[:, 1], w[:, 2]), np.hypot(0.9, 0.9), rtol=1e-6)
    assert off_axis_rate(mpc) < 0.3 * np.linalg.norm(mpc.angular_velocity_rad_s[0])
    assert mpc_metrics["spin_alignment_final"] > 0.95 > open_metrics["spin_alignment_final"]
    assert mpc_metrics["wy_final"] > 1.0  # from -0.9 rad/s: turned to +y, the reference's sign
    # solves: every re-plan (80 in 8 s) produced an executable plan
    ok = mpc.extras["mpc_solve_ok"][np.isfinite(mpc.extras["mpc_solve_ok"])]
    assert len(ok) == 80 and np.all(ok == 1.0)


def test_final_spin_rate_is_angular_momentum_over_inertia(spin) -> None:
    """w_y = |H| cos(theta) / Iyy: the final inertia, not the reference, sets 1.28 rad/s."""
    _, metrics = spin["mpc"]
    expected = metrics["wy_from_momentum"] * metrics["spin_alignment_final"]
    assert metrics["wy_final"] == pytest.approx(expected, rel=0.02)


def test_spin_stabilization_meets_the_papers_figures(spin) -> None:
    """Issue 4: |w_x|, |w_z| < 0.01 rad/s by 8 s, spin about y, settled within 3 s."""
    _, metrics = spin["mpc"]
    assert metrics["residual_wx"] < 0.01 and metrics["residual_wz"] < 0.01
    assert metrics["spin_alignment_final"] >= 0.99
    assert metrics["settling_time_s"] <= 3.0


def test_the_papers_formulation_turns_slower_than_the_momentum_one(spin) -> None:
    """The paper's 0.5 s horizon on ``w - w_ref`` inflates the inertia and turns slowly
    (splitter_mpc.core.mpc): the reason the scenario flies the momentum formulation."""
    _, paper = spin["paper_mpc"]
    _, ours = spin["mpc"]
    assert paper["time_constant_s"] > 1.5 * ours["time_constant_s"]
    assert paper["residual_wz"] > 10.0 * ours["residual_wz"]
    assert ours["spin_alignment_final"] > paper["spin_alignment_final"] > 0.9


def test_quaternion_tracking_needs_a_wider_inertia_range(orientation) -> None:
    """Paper section VII.A.2: 'quaternion tracking requires a broader range of inertia'."""
    quaternion, q_metrics, _ = orientation["quaternion_tracking"]
    velocity, v_metrics, _ = orientation["velocity_only"]
    assert q_metrics["radii_range_m"] > 2.0 * v_metrics["radii_range_m"]
    # the scenario's finding 1, measured on the principal moments: 60 vs 22 kg m^2
    assert q_metrics["inertia_range_kg_m2"] > 2.0 * v_metrics["inertia_range_kg_m2"]
    for series in (quaternion, velocity):
        assert np.all(np.isfinite(series.angular_velocity_rad_s))
        h = np.linalg.norm(series.extras["angular_momentum_world"], axis=1)
        assert np.max(np.abs(h - h[0])) < 1e-3 * h[0]
        assert np.all(series.radii_m >= MODEL.radii_min_m - 1e-6)
        assert np.all(series.radii_m <= MODEL.radii_max_m + 1e-6)


def test_the_attitude_error_is_measured_against_the_reference_the_mpc_was_given(
    orientation,
) -> None:
    """The metric rebuilds the reference from the first sample; the MPC got it from the gait
    machine on the first tick. Both put body y along the conserved H (reachable)."""
    series, _, controller = orientation["quaternion_tracking"]
    reference = controller.reference
    assert reference.stamp_ns == 0
    given = np.array([reference.attitude_at(round(t * 1e9)) for t in series.t_s])
    rebuilt = attitude_reference_series(series, (0.0, 1.0, 0.0), "momentum_aligned")
    np.testing.assert_allclose(rebuilt, given, atol=1e-15)  # measured: bit-identical
    momentum = series.extras["angular_momentum_world"][0]
    for q in given[:: len(given) // 8]:
        np.testing.assert_allclose(
            rotation_matrix(q)[:, 1], momentum / np.linalg.norm(momentum), atol=1e-12
        )


def test_quaternion_tracking_reduces_the_final_attitude_error(orientation) -> None:
    """Issue 4, against the reachable reference (body y along +H, spin phase from w_ref).

    With quaternion tracking the MPC turns body y 135 deg onto +H and then holds the
    spin phase through Iyy: the reference spins at |w_ref| = 1 rad/s, which only
    Iyy = |H| / |w_ref| gives. Measured (8 s): 1.9 deg in the last 0.5 s, the tail of a
    nutation that peaks near 12 deg at 5 s and decays (0.3 deg by 12 s); 5 deg leaves
    3x margin. Without it Table II weighs w_y lightly (Q_w,y = 10, Q_t,y = 1), and the
    MPC settles about the nearer pole, -y (45 deg from the initial momentum): body y ends
    opposite H, 179 deg from the reference.
    """
    series, q_metrics, _ = orientation["quaternion_tracking"]
    _, v_metrics, _ = orientation["velocity_only"]
    q_error = q_metrics["attitude_error_final_deg"]
    v_error = v_metrics["attitude_error_final_deg"]
    assert q_error < 5.0
    assert v_error > q_error + 90.0
    assert q_metrics["spin_alignment_final"] > 0.99 and q_metrics["wy_final"] > 0.0
    assert v_metrics["wy_final"] < 0.0  # the other pole
    final = series.t_s >= series.t_s[-1] - 0.5
    momentum = np.linalg.norm(series.extras["angular_momentum_world"][0])
    iyy = np.mean(series.principal_inertia_kg_m2[final, 1])
    assert iyy == pytest.approx(momentum / 1.0, rel=0.02)  # |H| / |w_ref|


def test_angular_velocity_is_tracked_better_with_quaternion_tracking_here(orientation) -> None:
    """The paper's finding 2 (velocity tracked better *without* quaternion tracking) is not
    reproduced: without J_q the MPC settles about -y, the pole nearer the initial momentum
    (Table II weighs w_y lightly), so |w - w_ref| stays >= 1 rad/s; with J_q the reference
    pulls body y onto +H and w reaches w_ref (RMS over 8 s: 0.83 vs 1.55 rad/s)."""
    _, q_metrics, _ = orientation["quaternion_tracking"]
    _, v_metrics, _ = orientation["velocity_only"]
    assert v_metrics["w_tracking_rms_rad_s"] > 1.5 * q_metrics["w_tracking_rms_rad_s"]


def golden_samples(series) -> dict[str, np.ndarray]:
    grid = np.arange(0.0, series.t_s[-1] + 1e-9, GOLDEN_STEP_S)
    index = np.searchsorted(series.t_s, grid - 1e-9)
    np.testing.assert_allclose(series.t_s[index], grid, atol=1e-9)
    return {"t_s": grid} | {field: getattr(series, field)[index] for field in GOLDEN_ATOL}


def test_closed_loops_match_the_stored_golden_runs(spin, orientation) -> None:
    """Every run above, every 0.1 s, against the stored one (see GOLDEN for updating it)."""
    fixtures = {"spin_stabilization": spin, "orientation_tracking": orientation}
    runs = {f"{name}.{variant}": fixtures[name][variant][0] for name, variant in GOLDEN_RUNS}
    arrays = {
        f"{name}.{field}": value
        for name, series in runs.items()
        for field, value in golden_samples(series).items()
    }
    if os.environ.get("SPLITTER_UPDATE_GOLDEN") == "1":
        GOLDEN.parent.mkdir(exist_ok=True)
        np.savez_compressed(GOLDEN, **arrays)
    with np.load(GOLDEN) as stored:
        assert sorted(stored.files) == sorted(arrays), "runs or fields differ from the stored ones"
        for key, value in arrays.items():
            field = key.rsplit(".", 1)[1]
            np.testing.assert_allclose(
                value, stored[key], rtol=0.0, atol=GOLDEN_ATOL.get(field, 1e-9), err_msg=key
            )


def test_solver_failures_mid_run_are_survived() -> None:
    failures = (1.0, 1.1, 1.2)  # [s] three re-plans in a row
    series, _ = run("spin_stabilization", "mpc", fail_solves_at_s=failures, duration_s=2.0)
    reference, _ = run("spin_stabilization", "mpc", duration_s=2.0)
    ok = series.extras["mpc_solve_ok"]
    replans = np.isfinite(ok)
    failed_at = np.round(series.t_s[replans & (ok == 0.0)], 3)
    assert failed_at.tolist() == list(failures)
    assert np.all(ok[replans & (series.t_s > 1.25)] == 1.0)  # recovered at the next re-plan
    assert np.all(np.isfinite(series.inertia_setpoint_kg_m2))
    before = series.t_s < 1.0
    np.testing.assert_array_equal(
        series.inertia_setpoint_kg_m2[before], reference.inertia_setpoint_kg_m2[before]
    )
    # 300 ms on the previous plan's tail changed the flight (the failures were real) ...
    assert np.max(np.abs(series.angular_velocity_rad_s - reference.angular_velocity_rad_s)) > 0
    # ... and the body still obeys physics: |H| conserved, radii within reach
    h = np.linalg.norm(series.extras["angular_momentum_world"], axis=1)
    assert np.max(np.abs(h - h[0])) < 1e-3 * h[0]
    assert np.all(series.radii_m <= MODEL.radii_max_m + 1e-6)


def test_an_open_loop_library_run_starts_no_solver_worker() -> None:
    """A disabled controller never solves: its MPC never builds its back-end (~1 s)."""
    scenario = load_scenario("spin_stabilization", "open_loop")
    with library_controller(MODEL, controller_config(scenario)) as open_loop:
        run_closed_loop(scenario, model=MODEL, controller=open_loop, duration_s=0.5)
        assert open_loop.mpc.backend is None
    with library_controller(MODEL, controller_config(load_scenario("spin_stabilization"))) as mpc:
        assert mpc.mpc.backend is not None  # an enabled one starts it with the controller
