"""Flight metrics against closed forms: step responses, steady spins, attitude errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from splitter_bringup.analysis.metrics import (
    SETTLING_BAND,
    Metric,
    attitude_error_rad,
    attitude_reference_series,
    evaluate_findings,
    flight_summary,
    step_response,
    w_tracking_rms,
)
from splitter_bringup.analysis.series import RunSeries
from splitter_bringup.scenario.definition import PaperFinding
from splitter_model.model import STANDARD_GRAVITY
from splitter_mpc.core.gait import (
    GaitConfig,
    GaitPhaseMachine,
    momentum_aligned_attitude,
    propagate_attitude,
)


def series(t, w, q=None, inertia=(0.48, 141.36, 141.36), radii=(2.8, 0.2, 0.2)) -> RunSeries:
    n = len(t)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)) if q is None else q
    inertia = np.tile(inertia, (n, 1))
    return RunSeries(
        t_s=np.asarray(t, dtype=float),
        angular_velocity_rad_s=np.asarray(w, dtype=float),
        orientation_wxyz=np.asarray(q, dtype=float),
        principal_inertia_kg_m2=inertia,
        inertia_setpoint_kg_m2=inertia.copy(),
        radii_m=np.tile(radii, (n, 1)),
        position_m=np.zeros((n, 3)),
        velocity_m_s=np.zeros((n, 3)),
        joint_position=np.zeros((n, 25)),
    )


def test_step_response_of_a_first_order_lag() -> None:
    t = np.linspace(0.0, 10.0, 20001)
    tau = 1.3  # [s]
    y = -0.9 + (1.28 + 0.9) * (1.0 - np.exp(-t / tau))
    time_constant, settling = step_response(t, y, 1.28)
    assert time_constant == pytest.approx(tau, abs=1e-3)
    assert settling == pytest.approx(-tau * math.log(SETTLING_BAND), abs=1e-3)  # 5.09 s


def test_steady_spin_about_y_matches_the_closed_forms() -> None:
    """A steady 1.28 rad/s spin at r_x = 2.8 m: the paper's 0.47 G and w_y = |H| / Iyy."""
    t = np.linspace(0.0, 8.0, 1601)
    w = np.tile([0.0, 1.28, 0.0], (len(t), 1))
    q = np.array([propagate_attitude([1, 0, 0, 0], [0, 1.28, 0], s) for s in t])
    metrics = flight_summary(series(t, w, q), {"max_g": 0.47})
    assert metrics["max_g"].value == pytest.approx(1.28**2 * 2.8 / STANDARD_GRAVITY, rel=1e-9)
    assert metrics["max_g"].value == pytest.approx(0.47, abs=0.005)
    assert metrics["max_g"].paper == 0.47
    assert metrics["wy_from_momentum"].value == pytest.approx(1.28, rel=1e-12)
    assert metrics["residual_wx"].value == 0.0 and metrics["spin_alignment_final"].value == 1.0
    assert metrics["energy_start_j"].value == pytest.approx(0.5 * 141.36 * 1.28**2)
    # the attitude reference turns at 1 rad/s, the body at 1.28: 0.28 rad/s apart
    err = attitude_error_rad(series(t, w, q), [0.0, 1.0, 0.0])
    np.testing.assert_allclose(err[:400], 0.28 * t[:400], atol=1e-9)


def test_round_off_rates_are_no_spin_on_either_backend() -> None:
    """A jump without spin: exact zeros (library) and 1e-7 rad/s noise (graph) agree."""
    t = np.linspace(0.0, 4.0, 801)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (len(t), 1))
    still = flight_summary(series(t, np.zeros((len(t), 3)), q), w_ref_rad_s=(0.0, 0.0, 0.0))
    noise = 1e-7 * np.column_stack([np.sin(3 * t), np.cos(2 * t) * t, np.sin(t)])
    noisy = flight_summary(series(t, noise, q), w_ref_rad_s=(0.0, 0.0, 0.0))
    for name in ("time_constant_s", "settling_time_s", "spin_alignment_final"):
        assert still[name].value == noisy[name].value == 0.0, name
    # a real spin-up still has its step and its axis
    spin = np.column_stack([np.zeros_like(t), 1.0 - np.exp(-t), np.zeros_like(t)])
    spun = flight_summary(series(t, spin, q), w_ref_rad_s=(0.0, 0.0, 0.0))
    assert spun["time_constant_s"].value > 0.5 and spun["spin_alignment_final"].value == 1.0


def test_attitude_error_counts_q_and_minus_q_as_one_attitude() -> None:
    t = np.linspace(0.0, 2.0, 201)
    q = np.array([propagate_attitude([1, 0, 0, 0], [0, 1.0, 0], s) for s in t])
    q[::2] *= -1.0
    err = attitude_error_rad(series(t, np.tile([0, 1.0, 0], (len(t), 1)), q), [0, 1.0, 0])
    assert np.max(err) < 1e-7


def test_momentum_aligned_error_is_measured_against_the_gait_machines_reference() -> None:
    """The metric rebuilds, from the first sample, the reference the gait machine made then."""
    t = np.linspace(0.0, 3.0, 601)
    q0 = np.array([0.9898, 0.0375, 0.0489, 0.1284])
    q0 /= np.linalg.norm(q0)
    w = np.tile([0.5, -0.5, 0.5], (len(t), 1))
    inertia = (0.48, 141.36, 141.36)
    w_ref = np.array([0.0, 1.0, 0.0])
    machine = GaitPhaseMachine(GaitConfig(attitude_reference="momentum_aligned"))
    out = machine.update(0, (0, 0, 10), (0, 0, 0), q0, w[0], 1.4, (0.0, 0.0), inertia)
    expected = np.array([out.reference.attitude_at(round(s * 1e9)) for s in t])
    held = series(t, w, np.tile(q0, (len(t), 1)), inertia=inertia)
    refs = attitude_reference_series(held, w_ref, "momentum_aligned")
    np.testing.assert_allclose(refs, expected, atol=1e-15)
    # a body holding q0 starts 135 deg (body y to H) from it; one on the reference after
    # the first sample, 0 from then on
    err = attitude_error_rad(held, w_ref, "momentum_aligned")
    assert math.degrees(err[0]) == pytest.approx(135.0, abs=0.2)
    flying = series(t, w, np.vstack([q0, expected[1:]]), inertia=inertia)
    err = attitude_error_rad(flying, w_ref, "momentum_aligned")
    assert math.degrees(err[0]) == pytest.approx(135.0, abs=0.2)
    assert np.max(err[1:]) < 1e-7
    # the paper's reference starts at q0 itself
    assert attitude_error_rad(held, w_ref, "integrate_w_ref")[0] < 1e-7
    np.testing.assert_allclose(
        refs[0], momentum_aligned_attitude(q0, w[0], inertia, w_ref), atol=1e-15
    )


def test_w_tracking_rms_of_a_constant_and_of_a_ramp_error() -> None:
    t = np.linspace(0.0, 4.0, 4001)
    constant = np.tile([0.3, 1.0 + 0.4, 0.0], (len(t), 1))  # |w - w_ref| = 0.5
    assert w_tracking_rms(t, constant, (0.0, 1.0, 0.0)) == pytest.approx(0.5, rel=1e-12)
    ramp = np.zeros((len(t), 3))
    ramp[:, 2] = 0.25 * t  # e = a t on [0, T]: RMS = a T / sqrt(3)
    assert w_tracking_rms(t, ramp, (0.0, 0.0, 0.0)) == pytest.approx(1.0 / math.sqrt(3), rel=1e-6)
    # time weighted: a coarse second half does not change the value
    uneven = np.concatenate([np.linspace(0.0, 2.0, 2001), np.linspace(2.5, 4.0, 4)])
    ramp_uneven = np.zeros((len(uneven), 3))
    ramp_uneven[:, 2] = 0.25 * uneven
    assert w_tracking_rms(uneven, ramp_uneven, (0, 0, 0)) == pytest.approx(
        1.0 / math.sqrt(3), rel=0.01
    )


def test_inertia_range_is_the_largest_range_of_a_principal_moment() -> None:
    t = np.linspace(0.0, 1.0, 11)
    run = series(t, np.zeros((len(t), 3)))
    run.principal_inertia_kg_m2[:, 1] = np.linspace(141.36, 163.0, len(t))
    run.principal_inertia_kg_m2[:, 2] = np.linspace(141.36, 131.36, len(t))
    assert flight_summary(run)["inertia_range_kg_m2"].value == pytest.approx(163.0 - 141.36)


def test_findings_compare_a_metric_between_two_variants() -> None:
    def metric(value: float) -> dict[str, Metric]:
        return {"inertia_range_kg_m2": Metric(value, "kg m^2", "")}

    wider = PaperFinding("wider", "inertia_range_kg_m2", "q", ">", "v")
    narrower = PaperFinding("narrower", "inertia_range_kg_m2", "q", "<", "v")
    results = evaluate_findings([wider, narrower], {"q": metric(60.0), "v": metric(21.6)})
    assert [r.reproduced for r in results] == [True, False]
    assert results[0].values == {"q": 60.0, "v": 21.6}
    assert evaluate_findings([wider], {"q": metric(60.0)})[0].reproduced is None
    with pytest.raises(KeyError, match="no_such"):
        evaluate_findings(
            [PaperFinding("x", "no_such", "q", ">", "v")], {"q": metric(1), "v": metric(2)}
        )
