"""A scenario's jump plan and attitude mode reach the gait phase manager's configuration."""

from __future__ import annotations

from pathlib import Path

import yaml

from splitter_bringup.scenario.definition import load_scenario
from splitter_mpc.core.gait import (
    GaitConfig,
    PlannedJump,
    gait_config_from_parameters,
    jump_plan_from_arrays,
    jump_plan_parameters,
)

CONFIG_FILE = (
    Path(__file__).resolve().parents[1]
    / "splitter_ws/src/splitter_mpc/config/gait_phase_manager.yaml"
)


def test_scenario_plan_round_trips_through_parameters() -> None:
    scenario = load_scenario("lunar_jumping")
    params = jump_plan_parameters(scenario.jumps)
    plan = jump_plan_from_arrays(
        params["jump_times_s"],
        params["jump_forces_n"],
        params["jump_durations_s"],
        params["jump_hemis"],
        params["jump_forces_b_n"],
    )
    assert plan == tuple(PlannedJump.from_spec(j) for j in scenario.jumps)
    # The launch: both hemis at once, each its own push (a couple: the spin); the second
    # jump shared by the hemis in stance.
    assert [j.hemi for j in plan] == ["both", "auto"]
    assert plan[0].force_n[1] == -plan[0].force_b_n[1] != 0.0
    assert plan[1].time_ns == 5_000_000_000 and plan[0].duration_ns == 600_000_000


def test_config_from_the_shipped_parameters_and_a_scenario() -> None:
    params = yaml.safe_load(CONFIG_FILE.read_text(encoding="utf-8"))
    params = params["gait_phase_manager"]["ros__parameters"]
    scenario = load_scenario("lunar_jumping")
    params.update(jump_plan_parameters(scenario.jumps))
    params["attitude_reference"] = scenario.controller.attitude_reference
    config = gait_config_from_parameters(params)
    assert config.jumps == tuple(PlannedJump.from_spec(j) for j in scenario.jumps)
    assert config.liftoff_debounce_ns == round(params["liftoff_debounce_s"] * 1e9)
    assert config.landed_dwell_ns == round(params["landed_dwell_s"] * 1e9)
    assert config.w_ref_rad_s == tuple(params["w_ref_rad_s"])
    assert gait_config_from_parameters({}) == GaitConfig()
