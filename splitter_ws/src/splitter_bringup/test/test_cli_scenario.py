"""The ``splitter`` command and the scenario files."""

from __future__ import annotations

import numpy as np
import pytest

from splitter_bringup.cli import main as cli
from splitter_bringup.scenario.definition import ScenarioError, available_scenarios, load_scenario


def test_help_lists_installed_subcommands(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["--help"]) == 0
    out = capsys.readouterr().out
    assert "bench" in out
    for name in cli.available():
        assert name in out


def test_unknown_subcommand_is_an_error() -> None:
    with pytest.raises(SystemExit) as info:
        cli.main(["no-such-command"])
    assert info.value.code == 2


def test_shipped_scenarios_load_with_paper_numbers() -> None:
    assert {"spin_stabilization", "orientation_tracking", "lunar_jumping"} <= set(
        available_scenarios()
    )
    spin = load_scenario("spin_stabilization")
    np.testing.assert_allclose(spin.initial_angular_velocity_rad_s, [-0.3, -0.9, 0.9])
    assert spin.controller.r == (0.01, 1.0, 1.0)
    assert spin.variants == ("mpc", "paper_mpc", "open_loop", "recovery")
    c = spin.controller
    assert (c.objective, c.horizon, c.dt_s, c.integrator) == ("momentum", 25, 0.1, "rk4")
    assert c.weights_step_s == 0.05  # Table I's weights per 50 ms, on a 100 ms grid
    paper = load_scenario("spin_stabilization", "paper_mpc").controller
    assert (paper.objective, paper.dt_s, paper.q_w) == ("paper", 0.01, (100.0, 100.0, 100.0))
    assert (paper.horizon, paper.integrator, paper.weights_step_s) == (50, "euler", None)
    assert not load_scenario("spin_stabilization", "open_loop").controller.enabled
    # Table I's variant: recovery only for tumbles too slow for the reference spin
    assert (c.recovery_spin_rad_s, c.recovery_momentum_ratio_max) == (2.0, 1.0)
    recovery = load_scenario("spin_stabilization", "recovery").controller
    assert (recovery.recovery_spin_rad_s, recovery.objective) == (2.0, "momentum")
    assert recovery.recovery_momentum_ratio_max is None  # any tumble
    assert load_scenario("spin_stabilization", "paper_mpc").controller.recovery_spin_rad_s == 0.0
    orient = load_scenario("orientation_tracking", "velocity_only")
    assert orient.controller.q_q == 0.0
    assert orient.controller.attitude_reference == "momentum_aligned"
    assert (orient.controller.objective, orient.controller.dt_s) == ("momentum", 0.05)
    assert load_scenario("orientation_tracking").variants[:3] == (
        "quaternion_tracking",
        "velocity_only",
        "open_loop",
    )
    lunar = load_scenario("lunar_jumping")
    assert lunar.gravity_m_s2 == pytest.approx(9.80665 / 6)
    assert [j.time_s for j in lunar.jumps] == [0.0, 5.0]


def test_bad_scenario_names_the_field(tmp_path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("duration_s: -1\n")
    with pytest.raises(ScenarioError, match="duration_s"):
        load_scenario(bad)
    with pytest.raises(ScenarioError, match="not found"):
        load_scenario("no_such_scenario")
    for field, value in (
        ("objective", "nope"),
        ("integrator", "nope"),
        ("dt_s", "-0.05"),
        ("horizon", "1"),
        ("horizon", "2.5"),
        ("weights_step_s", "0"),
        ("attitude_reference", "nope"),
        ("recovery_spin_rad_s", "-1.0"),
        ("recovery_spin_rad_s", ".nan"),
        ("recovery_momentum_ratio_max", "0"),
        ("recovery_momentum_ratio_max", "-1"),
        ("fault_effort_scale", "0"),
        ("fault_effort_scale", "1.5"),
        ("fault_effort_scale", ".nan"),
        ("solver", "nope"),
    ):
        bad.write_text(f"duration_s: 1\ncontroller:\n  {field}: {value}\n")
        with pytest.raises(ScenarioError, match=field):
            load_scenario(bad)


def test_a_scenario_names_the_mpc_back_end_the_graph_and_the_library_fly(tmp_path) -> None:
    from splitter_bringup.run.library import controller_config
    from splitter_bringup.scenario.graph_config import mpc_parameters

    assert load_scenario("spin_stabilization").controller.solver == "fatrop"
    path = tmp_path / "condensed.yaml"
    path.write_text("duration_s: 1\ncontroller: {solver: condensed_sqp}\n")
    scenario = load_scenario(path)
    assert scenario.controller.solver == "condensed_sqp"
    assert mpc_parameters(scenario)["solver"] == "condensed_sqp"
    assert mpc_parameters(scenario, real_time=True)["solver"] == "condensed_sqp"
    assert controller_config(scenario).mpc.solver == "condensed_sqp"


def test_findings_are_comparisons_between_variants(tmp_path) -> None:
    findings = load_scenario("orientation_tracking").findings
    assert [(f.metric, f.expectation) for f in findings[:2]] == [
        ("inertia_range_kg_m2", "quaternion_tracking > velocity_only"),
        ("w_tracking_rms_rad_s", "velocity_only < quaternion_tracking"),
    ]
    bad = tmp_path / "bad.yaml"
    head = "duration_s: 1\nvariants: {a: {}, b: {}}\nfindings:\n"
    for item, message in (
        ("  - {statement: s, metric: m, expect: a >= b}", "expect"),
        ("  - {statement: s, metric: m, expect: a > c}", "no variant 'c'"),
        ("  - {statement: s, expect: a > b}", "keys statement, metric, expect"),
        ("  statement: s", "a list"),
    ):
        bad.write_text(head + item + "\n")
        with pytest.raises(ScenarioError, match=message):
            load_scenario(bad)


def test_build_mpc_builds_each_formulation_the_scenarios_fly_once() -> None:
    from splitter_bringup.cli.build_mpc import formulations

    found = {
        key: f"{scenario.name}/{scenario.variant}"
        for key, scenario in formulations(available_scenarios()).items()
    }
    # the first variant (in name order) flying a formulation builds it; the attitude is
    # in the state only where the weights track it
    assert found[50, 0.05, "euler", True] == "orientation_tracking/quaternion_tracking"
    assert found[50, 0.05, "euler", False] == "orientation_tracking/velocity_only"
    assert found[50, 0.01, "euler", False].startswith("lunar_jumping/")
    assert found[25, 0.1, "rk4", False] == "spin_stabilization/mpc"
    assert len(found) == len(set(found.values()))
