"""Monte-Carlo campaigns: draws, the success test, failure modes, Wilson interval, end to end."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from splitter_bringup.analysis.campaign import (
    FAILURE_MODES,
    OUTCOMES,
    Draw,
    DrawResult,
    PerturbationSpec,
    binned_by_speed,
    classify_flight,
    direction_angles_deg,
    draw_campaign,
    draw_seeds,
    make_draw,
    settling_time,
    summarize,
    wilson_interval,
)
from splitter_bringup.analysis.series import RunSeries
from splitter_bringup.cli.main import main as splitter

T = np.arange(0.0, 4.0 + 1e-9, 0.005)  # [s] a 4 s flight sampled every 5 ms


def spin(axis_rate: tuple[float, float, float], decay_s: float = 0.5) -> np.ndarray:
    """A body rate that starts tumbling and ends at ``axis_rate`` (exponential approach)."""
    start = np.array([0.6, 0.6, 0.6])
    k = np.exp(-T / decay_s)[:, None]
    return k * start + (1.0 - k) * np.asarray(axis_rate)


# --- the classifier on hand-made trajectories --------------------------------------------
def test_a_spin_settled_about_y_is_a_success_with_its_settling_time() -> None:
    w = spin((0.0, -1.2, 0.0), decay_s=0.4)  # either spin sense counts
    outcome = classify_flight(T, w)
    assert outcome.success and outcome.failure_mode == "" and outcome.outcome == "success"
    # |w_x| = |w_z| = 0.6 exp(-t / 0.4) < 0.01 from t = 0.4 ln 60 = 1.638 s (w_y is aligned)
    assert outcome.settling_time_s == pytest.approx(0.4 * math.log(60.0), abs=0.006)
    assert settling_time(T, w) == outcome.settling_time_s


def test_settling_time_is_the_last_entry_into_the_success_set() -> None:
    w = np.tile([0.0, 1.0, 0.0], (len(T), 1))
    w[(T > 2.0) & (T < 2.5), 0] = 0.05  # a excursion: settled again from 2.5 s
    assert settling_time(T, w) == pytest.approx(2.5)
    assert settling_time(T, np.tile([0.0, 1.0, 0.0], (len(T), 1))) == 0.0


def test_stuck_about_the_tether_axis_is_a_minor_axis_spin() -> None:
    outcome = classify_flight(T, spin((1.3, 0.05, 0.02)))
    assert not outcome.success and outcome.failure_mode == "minor_axis_spin"
    assert math.isnan(outcome.settling_time_s)


def test_settled_about_z_is_the_wrong_axis() -> None:
    assert classify_flight(T, spin((0.02, 0.0, -1.1))).failure_mode == "wrong_axis"


def test_aligned_with_y_but_above_tolerance_is_slow_convergence() -> None:
    outcome = classify_flight(T, spin((0.03, 1.2, 0.0), decay_s=3.0))
    assert outcome.failure_mode == "slow_convergence"


def test_no_dominant_axis_is_tumbling() -> None:
    phase = 2.0 * np.pi * 0.7 * T  # a precessing tumble: w turns about z
    w = np.stack([0.8 * np.cos(phase), 0.8 * np.sin(phase), 0.6 * np.ones_like(T)], axis=1)
    assert classify_flight(T, w).failure_mode == "tumbling"


def test_mpc_counts_name_the_failure_and_a_deadline_miss_comes_first() -> None:
    w = spin((0.02, 0.0, -1.1))
    assert classify_flight(T, w, mpc_failures=3).failure_mode == "solver_failure"
    assert classify_flight(T, w, mpc_failures=3, deadline_misses=1).failure_mode == (
        "deadline_miss"
    )
    # a success stays one, whatever the solver did on the way
    assert classify_flight(T, spin((0.0, 1.2, 0.0)), mpc_failures=2, deadline_misses=1).success


def test_non_finite_or_blown_up_rates_diverged_and_exceptions_are_errors() -> None:
    w = spin((0.0, 1.2, 0.0))
    bad = w.copy()
    bad[100, 1] = np.nan
    assert classify_flight(T, bad).failure_mode == "diverged"
    blown = w.copy()
    blown[-1] = [0.0, 50.0, 0.0]  # 10 x |w0| = 10.4 rad/s exceeded (and aligned with y)
    assert classify_flight(T, blown).failure_mode == "diverged"
    assert classify_flight(T, np.zeros((len(T), 3))).failure_mode == "diverged"
    assert classify_flight(T, w, error="RuntimeError('x')").failure_mode == "error"
    assert classify_flight([], np.zeros((0, 3))).failure_mode == "error"


def test_every_mode_is_an_outcome() -> None:
    assert set(FAILURE_MODES) | {"success"} == set(OUTCOMES)


# --- statistics ----------------------------------------------------------------------------
def test_wilson_interval_against_the_textbook_value() -> None:
    # 8 successes of 10: the Wilson score interval (z = 1.96) is [0.4902, 0.9433]
    lo, hi = wilson_interval(8, 10)
    assert lo == pytest.approx(0.4902, abs=1e-4) and hi == pytest.approx(0.9433, abs=1e-4)
    z = 1.959963984540054
    n, p = 200, 0.71
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    assert wilson_interval(142, 200) == pytest.approx((centre - half, centre + half), abs=1e-12)
    assert wilson_interval(0, 5)[0] == 0.0 and wilson_interval(5, 5)[1] == 1.0
    assert all(math.isnan(v) for v in wilson_interval(0, 0))


def result(draw: Draw, outcome: str, settling: float = math.nan) -> DrawResult:
    ok = outcome == "success"
    mode = "" if ok else outcome
    return DrawResult(draw, ok, mode, settling, (0.0, 1.0, 0.0), 80, 0, 0, 1.0)


def test_summary_counts_every_mode_and_the_settling_percentiles() -> None:
    draws = draw_campaign(seed=3, count=10)
    outcomes = ["success"] * 7 + ["minor_axis_spin", "minor_axis_spin", "wrong_axis"]
    settle = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]
    results = [
        result(d, o, settle[i] if o == "success" else math.nan)
        for i, (d, o) in enumerate(zip(draws, outcomes, strict=True))
    ]
    summary = summarize(results).as_dict()
    assert summary["successes"] == 7 and summary["success_rate"] == 0.7
    assert summary["success_rate_wilson_95"] == pytest.approx(list(wilson_interval(7, 10)))
    assert summary["failure_mode_counts"]["minor_axis_spin"] == 2
    assert summary["failure_mode_counts"]["wrong_axis"] == 1
    assert set(summary["failure_mode_counts"]) == set(FAILURE_MODES)
    assert summary["settling_time_median_s"] == 4.0
    assert summary["settling_time_p90_s"] == pytest.approx(6.4)
    bins = binned_by_speed(results, 0.5, 1.8, bins=4)
    assert bins.draws.sum() == 10 and bins.successes.sum() == 7


# --- draws ---------------------------------------------------------------------------------
def test_each_draw_replays_alone_from_its_own_seed() -> None:
    draws = draw_campaign(seed=1, count=50, w_min_rad_s=0.5, w_max_rad_s=1.8)
    assert draw_seeds(1, 5) == [d.seed for d in draws[:5]]  # independent of the count
    again = make_draw(17, draws[17].seed)
    assert again == draws[17]
    speeds = np.array([d.w0_norm_rad_s for d in draws])
    assert np.all((speeds >= 0.5) & (speeds <= 1.8))
    assert len({d.seed for d in draws}) == 50
    # perturbations never move the initial condition of a draw
    perturbed = make_draw(17, draws[17].seed, perturbation=PerturbationSpec(0.1, 0.01, 0.01, 0.1))
    assert perturbed.w0_rad_s == again.w0_rad_s and perturbed.euler_deg == again.euler_deg
    assert all(0.9 <= f <= 1.1 for f in perturbed.mass_scale) and perturbed.mass_scale != (1, 1, 1)
    assert all(abs(b) <= 0.01 for b in perturbed.gyro_bias_rad_s)
    assert again.mass_scale == (1.0, 1.0, 1.0) and again.gyro_bias_rad_s == (0.0, 0.0, 0.0)


def test_directions_cover_the_sphere_uniformly() -> None:
    draws = draw_campaign(seed=5, count=2000)
    w = np.array([d.w0_rad_s for d in draws])
    unit = w / np.linalg.norm(w, axis=1)[:, None]
    assert np.abs(unit.mean(axis=0)).max() < 0.05  # no preferred direction
    assert np.abs((unit**2).mean(axis=0) - 1.0 / 3.0).max() < 0.03
    azimuth, elevation = direction_angles_deg(w)
    assert np.all(np.abs(azimuth) <= 180.0) and np.all(np.abs(elevation) <= 90.0)


# --- the command, end to end ------------------------------------------------------------
@pytest.mark.slow
def test_campaign_on_two_local_workers_writes_its_files_and_replays(tmp_path, capsys) -> None:
    out = tmp_path / "campaign"
    args = ["campaign", "spin_stabilization", "--draws", "3", "--seed", "1"]
    args += ["--duration", "1.0", "--workers", "2", "--out", str(out), "--yaml", "all"]
    assert splitter(args) == 0
    rows = list(csv.DictReader((out / "draws.csv").open()))
    assert [int(r["index"]) for r in rows] == [0, 1, 2]
    assert [int(r["seed"]) for r in rows] == draw_seeds(1, 3)
    for row in rows:
        assert row["outcome"] in OUTCOMES and row["error"] == ""
        assert int(row["mpc_solves"]) == 10  # 1 s at a re-plan every 0.1 s
        assert 0.5 <= float(row["w0_norm_rad_s"]) <= 1.8
    document = json.loads((out / "campaign.json").read_text())
    assert document["draws"] == 3 and document["variant"] == "mpc"
    assert document["duration_s"] == 1.0
    assert document["cluster"]["workers"] == 2
    assert document["cluster"]["scheduler"].startswith("tcp://127.0.0.1:")
    assert sum(document["outcome_counts"].values()) == 3
    lo, hi = document["success_rate_wilson_95"]
    assert 0.0 <= lo <= document["success_rate"] <= hi <= 1.0
    assert [d["seed"] for d in document["per_draw"]] == draw_seeds(1, 3)
    for name in ("success_vs_speed.png", "outcome_directions.png"):
        assert (out / name).stat().st_size > 0
    assert "success rate" in capsys.readouterr().out
    # the scenario file of draw 1 flies the very same flight with `splitter run`
    entry = document["per_draw"][1]
    assert "--replay" in entry["replay"]
    run_out = tmp_path / "run"
    run_args = ["run", entry["scenario_yaml"], "--no-ros", "--out", str(run_out)]
    assert splitter([*run_args, "--no-plots", "--no-animation"]) == 0
    w_end = RunSeries.load_npz(run_out / "mpc.npz").angular_velocity_rad_s[-1]
    expected = [float(rows[1][f"w_final_{a}_rad_s"]) for a in "xyz"]
    assert w_end.tolist() == expected


@pytest.mark.slow
def test_a_perturbed_campaign_on_an_existing_scheduler_replays_a_draw_alone(tmp_path) -> None:
    import shlex

    from distributed import LocalCluster

    from splitter_bringup.scenario.definition import load_scenario

    out = tmp_path / "campaign"
    args = ["campaign", "spin_stabilization", "--draws", "2", "--seed", "4", "--duration", "0.5"]
    args += ["--perturb-mass", "--imu-noise", "--imu-bias", "--actuator-lag", "--no-plots"]
    with LocalCluster(
        n_workers=1,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address="127.0.0.1:0",
    ) as cluster:
        assert splitter([*args, "--scheduler", cluster.scheduler_address, "--out", str(out)]) == 0
    document = json.loads((out / "campaign.json").read_text())
    assert document["cluster"]["embedded_local_cluster"] is False
    assert document["perturbation"]["mass_fraction"] == 0.1
    rows = list(csv.DictReader((out / "draws.csv").open()))
    assert {float(rows[0][f"mass_scale_{a}"]) for a in "xyz"} != {1.0}
    for path in (out / "draws").glob("*.yaml"):  # failed draws, with their robot errors
        assert load_scenario(path).robot_errors.present
    # the replay command of draw 1 flies it alone, the same flight
    words = shlex.split(document["per_draw"][1]["replay"])
    assert words[:2] == ["splitter", "campaign"] and "--imu-noise" in words
    assert splitter(words[1:]) == 0
    replay_dir = out / f"replay_{rows[1]['seed']}"
    replayed = next(csv.DictReader((replay_dir / "draws.csv").open()))
    for key in ("seed", "w_final_x_rad_s", "w_final_y_rad_s", "w_final_z_rad_s", "outcome"):
        assert replayed[key] == rows[1][key]
    assert (replay_dir / "replay_flight.png").stat().st_size > 0


def test_campaign_rejects_bad_input(tmp_path, capsys) -> None:
    out = str(tmp_path)
    assert splitter(["campaign", "nope", "--draws", "2", "--out", out]) == 2
    assert splitter(["campaign", "spin_stabilization", "--draws", "0", "--out", out]) == 2
    assert splitter(["campaign", "spin_stabilization", "--variant", "x", "--out", out]) == 2
    assert "variant 'x'" in capsys.readouterr().err


# --- the draws' robot errors in the closed loop ------------------------------------------
@pytest.mark.slow
def test_the_closed_loop_flies_the_draws_robot_errors() -> None:
    from dataclasses import replace

    from splitter_bringup.analysis.campaign import robot_errors_for_draw
    from splitter_bringup.run.library import run_closed_loop
    from splitter_bringup.scenario.definition import load_scenario
    from splitter_sim.core.robot_errors import RobotErrors

    scenario = replace(load_scenario("spin_stabilization", "mpc"), duration_s=0.3)
    nominal = run_closed_loop(scenario)
    draw = make_draw(0, 7, perturbation=PerturbationSpec(mass_fraction=0.1))
    assert robot_errors_for_draw(draw, PerturbationSpec()) == RobotErrors()
    assert not replace(RobotErrors(), noise_seed=3).present  # a seed alone is no error
    same = run_closed_loop(replace(scenario, robot_errors=RobotErrors()))
    assert np.array_equal(nominal.angular_velocity_rad_s, same.angular_velocity_rad_s)
    heavy = robot_errors_for_draw(draw, PerturbationSpec(mass_fraction=0.1))
    flown = run_closed_loop(replace(scenario, robot_errors=heavy))
    # other masses, other inertia from the first sample on
    assert not np.allclose(flown.principal_inertia_kg_m2[0], nominal.principal_inertia_kg_m2[0])
    assert "estimate_masses_kg" in flown.extras  # the controllers flew on the estimator
    errors = RobotErrors(
        gyro_noise_rad_s=0.01, gyro_bias_rad_s=(0.01, 0.0, 0.0), actuator_lag_s=0.2, noise_seed=3
    )
    noisy = run_closed_loop(replace(scenario, robot_errors=errors), estimator=False)
    assert not np.array_equal(noisy.radii_m, nominal.radii_m)
    assert "estimate_masses_kg" not in noisy.extras
    # the true rate is recorded, not the gyro's reading: it starts where the scenario does
    assert np.array_equal(noisy.angular_velocity_rad_s[0], nominal.angular_velocity_rad_s[0])


def test_a_perturbed_draws_scenario_file_carries_its_robot_errors(tmp_path) -> None:
    import yaml

    from splitter_bringup.analysis.campaign import robot_errors_for_draw, scenario_document
    from splitter_bringup.scenario.definition import load_scenario

    spec = PerturbationSpec(
        mass_fraction=0.1, gyro_noise_rad_s=0.002, gyro_bias_rad_s=0.005, actuator_lag_s=0.05
    )
    draw = make_draw(3, 11, 1.0, 1.8, spec)
    errors = robot_errors_for_draw(draw, spec)
    base = load_scenario("spin_stabilization", "mpc")
    path = tmp_path / "draw.yaml"
    path.write_text(yaml.safe_dump(scenario_document(base, draw, 8.0, errors), sort_keys=False))
    flown = load_scenario(path, "mpc")
    assert flown.robot_errors == errors and errors.present
    assert errors.mass_scale == draw.mass_scale and errors.noise_seed == draw.noise_seed
    plain = yaml.safe_load(yaml.safe_dump(scenario_document(base, draw, 8.0)))
    assert "robot_errors" not in plain


def test_hemi_bodies_are_boxes_drawn_after_everything_else(tmp_path) -> None:
    """``--hemi-bodies``: each body a solid box of m_x with edges in [e/2, e]; the other
    numbers of a draw stay as they were, and its scenario file flies the same robot with
    the estimator identifying the bodies."""
    import yaml

    from splitter_bringup.analysis.campaign import (
        HEMI_INERTIA_PRIOR_KG_M2,
        box_inertia,
        estimator_for_draw,
        robot_errors_for_draw,
        scenario_document,
    )
    from splitter_bringup.scenario.definition import load_scenario

    plain = PerturbationSpec(mass_fraction=0.1)
    bodies = PerturbationSpec(mass_fraction=0.1, hemi_body_edge_m=0.35)
    a, b = make_draw(5, 23, perturbation=plain), make_draw(5, 23, perturbation=bodies)
    assert a.hemi_inertia_kg_m2 == (0.0, 0.0, 0.0)
    assert (a.w0_rad_s, a.euler_deg, a.mass_scale, a.gyro_bias_rad_s, a.noise_seed) == (
        b.w0_rad_s,
        b.euler_deg,
        b.mass_scale,
        b.gyro_bias_rad_s,
        b.noise_seed,
    )
    j = np.array(b.hemi_inertia_kg_m2)
    m = 3.0 * b.mass_scale[0]  # [kg] the draw's body
    # a box of edges within [0.175, 0.35] m: each moment within m (2 (e/2)^2, 2 e^2) / 12
    assert np.all(j >= m * 2 * 0.175**2 / 12 - 1e-12) and np.all(j <= m * 2 * 0.35**2 / 12)
    assert j[0] <= j[1] + j[2] and j[1] <= j[0] + j[2] and j[2] <= j[0] + j[1]
    np.testing.assert_allclose(box_inertia(12.0, (1.0, 2.0, 3.0)), (13.0, 10.0, 5.0))
    errors = robot_errors_for_draw(b, bodies)
    assert errors.hemi_inertia_kg_m2 == b.hemi_inertia_kg_m2
    base = load_scenario("spin_stabilization", "mpc")
    assert estimator_for_draw(base, a) is base
    flown = estimator_for_draw(base, b)
    assert flown.estimator.hemi_inertia_prior_kg_m2 == HEMI_INERTIA_PRIOR_KG_M2
    path = tmp_path / "draw.yaml"
    path.write_text(yaml.safe_dump(scenario_document(base, b, 8.0, errors), sort_keys=False))
    loaded = load_scenario(path, "mpc")
    assert loaded.robot_errors == errors and loaded.estimator == flown.estimator


@pytest.mark.slow
def test_a_campaign_flies_the_solver_asked_for_and_replays_with_it(tmp_path) -> None:
    import shlex

    from splitter_bringup.analysis.campaign import scenario_for_draw
    from splitter_bringup.run.campaign import campaign_mpc, fly_draw
    from splitter_bringup.scenario.definition import load_scenario
    from splitter_mpc.core.solvers import LOCKSTEP_MAX_TIME_S

    assert campaign_mpc(None) is None  # the library's default MPC
    settings = campaign_mpc("condensed_sqp")
    assert settings.solver == "condensed_sqp"
    assert settings.options.max_time_s == LOCKSTEP_MAX_TIME_S
    out = tmp_path / "campaign"
    args = ["campaign", "spin_stabilization", "--draws", "1", "--seed", "2", "--duration", "1.0"]
    args += ["--solver", "condensed_sqp", "--workers", "1", "--no-plots", "--out", str(out)]
    assert splitter(args) == 0
    document = json.loads((out / "campaign.json").read_text())
    assert document["solver"] == "condensed_sqp"
    words = shlex.split(document["per_draw"][0]["replay"])
    assert words[words.index("--solver") + 1] == "condensed_sqp"
    # the same draw flown with each back-end: the same optimum, other iteration counts
    scenario = scenario_for_draw(load_scenario("spin_stabilization", "mpc"), make_draw(0, 5), 1.0)
    condensed = fly_draw(scenario, make_draw(0, 5), solver="condensed_sqp")
    fatrop = fly_draw(scenario, make_draw(0, 5))
    assert np.max(np.abs(condensed.angular_velocity_rad_s - fatrop.angular_velocity_rad_s)) < 0.01
    iterations = (np.nanmax(s.extras["mpc_iterations"]) for s in (condensed, fatrop))
    assert next(iterations) < next(iterations)  # SQP steps against interior-point iterations
