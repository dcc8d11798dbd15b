"""The scenario language's pushes: one hemi, shared, or both at once (a launch that adds
rotation), each field checked with an error naming it, nothing run."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from splitter_bringup.scenario.definition import JumpSpec, ScenarioError, load_scenario
from splitter_bringup.scenario.graph_config import gait_parameters
from splitter_mpc.core.gait import PlannedJump, gait_config_from_parameters

BOTH = "{time_s: 0.0, hemi: both, force_a_n: [0, 0, 200], force_b_n: [0, 0, 120], duration_s: 0.6}"


def _scenario(tmp_path: Path, jumps: str) -> Path:
    path = tmp_path / "pushes.yaml"
    path.write_text(f"duration_s: 1.0\ngravity: moon\njumps:\n  - {jumps}\n")
    return path


def test_both_hemis_push_at_once_each_its_own_force(tmp_path: Path) -> None:
    scenario = load_scenario(_scenario(tmp_path, BOTH))
    assert scenario.jumps == (
        JumpSpec(0.0, (0.0, 0.0, 200.0), 0.6, "both", force_b_n=(0.0, 0.0, 120.0)),
    )
    # Through the gait phase manager's parameters to its plan, unchanged.
    config = gait_config_from_parameters(gait_parameters(scenario))
    assert config.jumps == (
        PlannedJump(0, (0.0, 0.0, 200.0), 600_000_000, "both", (0.0, 0.0, 120.0)),
    )
    assert config.jumps[0].total_force_n == (0.0, 0.0, 320.0)


@pytest.mark.parametrize(
    ("jump", "field"),
    [
        ("{time_s: 0, force_n: [0, 0, .nan], duration_s: 0.6}", r"jumps\[0\]\.force_n"),
        ("{time_s: 0, force_n: [0, 0, .inf], duration_s: 0.6}", r"jumps\[0\]\.force_n"),
        ("{time_s: 0, force_n: [0, 0], duration_s: 0.6}", r"jumps\[0\]\.force_n"),
        ("{time_s: .nan, force_n: [0, 0, 1], duration_s: 0.6}", r"jumps\[0\]\.time_s"),
        ("{time_s: -1, force_n: [0, 0, 1], duration_s: 0.6}", r"jumps\[0\]\.time_s"),
        ("{time_s: 0, force_n: [0, 0, 1], duration_s: 0}", r"jumps\[0\]\.duration_s"),
        ("{time_s: 0, force_n: [0, 0, 1], duration_s: 0.6, hemi: c}", r"jumps\[0\]\.hemi"),
        ("{time_s: 0, force_n: [0, 0, 1], duration_s: 0.6, torque: 1}", r"jumps\[0\]\.torque"),
        (BOTH.replace("force_b_n", "force_n"), r"jumps\[0\]\.force_n: unknown"),
        (BOTH.replace("120]", ".nan]"), r"jumps\[0\]\.force_b_n"),
        ("{time_s: 0, force_a_n: [0, 0, 1], duration_s: 0.6}", r"jumps\[0\]\.force_a_n"),
    ],
)
def test_a_bad_push_names_its_field(tmp_path: Path, jump: str, field: str) -> None:
    with pytest.raises(ScenarioError, match=field):
        load_scenario(_scenario(tmp_path, jump))


def test_pushes_that_overlap_are_refused_and_told_how_to_push_both(tmp_path: Path) -> None:
    two = (
        "{time_s: 0, force_n: [0, 0, 60], duration_s: 0.1, hemi: a}\n"
        "  - {time_s: 0, force_n: [0, 0, 60], duration_s: 0.1, hemi: b}"
    )
    with pytest.raises(ScenarioError, match=r"jumps\[1\]\.time_s.*hemi: both"):
        load_scenario(_scenario(tmp_path, two))


@pytest.mark.parametrize(
    ("text", "field"),
    [
        ("duration_s: 1.0\ngroundd: {slope_deg: 5}\n", "groundd"),
        ("duration_s: 1.0\ninitial: {positon_m: [0, 0, 1]}\n", r"initial\.positon_m"),
        ("duration_s: 1.0\ncontroller: {q_ww: [1, 1, 1]}\n", r"controller\.q_ww"),
        (
            "duration_s: 1.0\nvariants: {v: {initial: {radius_m: [1, 1, 1]}}}\n",
            r"initial\.radius_m",
        ),
    ],
)
def test_a_misspelt_field_is_an_error_not_a_default(tmp_path: Path, text: str, field: str) -> None:
    path = tmp_path / "typo.yaml"
    path.write_text(text)
    with pytest.raises(ScenarioError, match=f"{field}: unknown field"):
        load_scenario(path)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        *(("leg_cone_half_angle_deg", v) for v in ("90", "0.5", "nan", "wide")),
        *(("leg_posture_stiffness_n_m", v) for v in ("-1", "2e6", "nan", "stiff")),
        *(("leg_ride_height_m", v) for v in ("-0.1", "0.41", "nan", "high")),
    ],
)
def test_a_legs_setting_out_of_range_names_its_field(
    tmp_path: Path, field: str, value: str
) -> None:
    path = tmp_path / "legs.yaml"
    path.write_text(f"name: c\nduration_s: 1.0\n{field}: {value}\n")
    with pytest.raises(ScenarioError, match=field):
        load_scenario(path)


def test_the_legs_cone_reaches_the_simulator_in_both_backends(tmp_path: Path) -> None:
    from splitter_bringup.scenario.graph_config import simulator_parameters
    from splitter_bringup.scenario.simulation import sim_config

    path = tmp_path / "cone.yaml"
    path.write_text("name: c\nduration_s: 1.0\ncompliant_legs: true\nleg_cone_half_angle_deg: 45\n")
    scenario = load_scenario(path)
    assert sim_config(scenario).leg_cone_half_angle_deg == 45.0
    assert simulator_parameters(scenario, False, 1.0)["leg_cone_half_angle_deg"] == 45.0
    assert load_scenario("lunar_jumping").leg_cone_half_angle_deg == 60.0


def test_the_legs_posture_reaches_the_simulator_in_both_backends(tmp_path: Path) -> None:
    """Off unless a scenario asks (splitter_sim.core.legs "Ride height")."""
    from splitter_bringup.scenario.graph_config import simulator_parameters
    from splitter_bringup.scenario.simulation import sim_config

    path = tmp_path / "posture.yaml"
    path.write_text(
        "name: p\nduration_s: 1.0\ncompliant_legs: true\nleg_posture_stiffness_n_m: 300\n"
    )
    scenario = load_scenario(path)
    assert sim_config(scenario).legs.posture_stiffness_n_m == 300.0
    assert simulator_parameters(scenario, False, 1.0)["leg_posture_stiffness_n_m"] == 300.0
    assert load_scenario("lunar_jumping").leg_posture_stiffness_n_m == 0.0
    assert sim_config(load_scenario("lunar_jumping")).legs.posture_stiffness_n_m == 0.0


def test_the_ride_height_reaches_the_simulator_in_both_backends(tmp_path: Path) -> None:
    from splitter_bringup.scenario.graph_config import simulator_parameters
    from splitter_bringup.scenario.simulation import sim_config

    path = tmp_path / "ride.yaml"
    path.write_text(
        "name: p\nduration_s: 1.0\ncompliant_legs: true\nleg_posture_stiffness_n_m: 300\n"
        "leg_ride_height_m: 0.3\n"
    )
    scenario = load_scenario(path)
    assert sim_config(scenario).legs.ride_compression_m == pytest.approx(0.1)
    assert simulator_parameters(scenario, False, 1.0)["leg_ride_height_m"] == 0.3
    assert sim_config(load_scenario("lunar_jumping")).legs.ride_compression_m == pytest.approx(0.2)


COUPLE = "{time_s: 0.0, hemi: auto, force_n: [160, 0, 320], couple_n: 52, duration_s: 0.6}"


def test_a_couple_reaches_the_gait_plan_and_needs_both_hemis(tmp_path: Path) -> None:
    scenario = load_scenario(_scenario(tmp_path, COUPLE))
    assert scenario.jumps[0].couple_n == 52.0
    config = gait_config_from_parameters(gait_parameters(scenario))
    assert config.jumps[0].couple_n == 52.0 and config.jumps[0].hemi == "auto"
    for jump, field in (
        (COUPLE.replace("hemi: auto", "hemi: a"), r"jumps\[0\]\.couple_n: needs both hemis"),
        (COUPLE.replace("couple_n: 52", "couple_n: .nan"), r"jumps\[0\]\.couple_n"),
        (COUPLE.replace("couple_n: 52", "couple_n: many"), r"jumps\[0\]\.couple_n"),
    ):
        with pytest.raises(ScenarioError, match=field):
            load_scenario(_scenario(tmp_path, jump))


@pytest.mark.parametrize("spin_up", ["-1", "11", ".nan", "fast"])
def test_a_bad_landing_spin_up_names_its_field(tmp_path: Path, spin_up: str) -> None:
    path = tmp_path / "spin_up.yaml"
    path.write_text(f"name: s\nduration_s: 1.0\ncontroller: {{landing_spin_up_rad_s: {spin_up}}}\n")
    with pytest.raises(ScenarioError, match=r"landing_spin_up_rad_s"):
        load_scenario(path)


def test_a_landing_spin_up_reaches_the_gait(tmp_path: Path) -> None:
    path = tmp_path / "spin_up.yaml"
    path.write_text(
        "name: s\nduration_s: 1.0\n"
        "controller: {attitude_reference: landing_timed, landing_spin_up_rad_s: 1.5}\n"
    )
    config = gait_config_from_parameters(gait_parameters(load_scenario(path)))
    assert config.landing_spin_up_rad_s == 1.5
    assert gait_config_from_parameters(
        gait_parameters(load_scenario("lunar_jumping"))
    ).landing_spin_up_rad_s == 0.0  # fmt: skip


def _launch_spin_rad_s(tmp_path: Path, jump: str, heading_deg: float) -> np.ndarray:
    """Body rate [rad/s] after a 1.2 s launch on the Moon, open loop, library backend."""
    from splitter_bringup.run.library import run_closed_loop

    path = tmp_path / "launch.yaml"
    path.write_text(
        "name: launch\nduration_s: 1.2\ngravity: moon\nground_contact: true\n"
        "compliant_legs: true\ncontroller: {enabled: false}\n"
        f"initial: {{position_m: [0, 0, 0.1997], orientation_euler_deg: [0, 0, {heading_deg}]}}\n"
        f"jumps:\n  - {jump}\n"
    )
    series = run_closed_loop(load_scenario(path))
    return series.angular_velocity_rad_s[-1]


def test_a_couple_launches_the_spin_a_world_couple_does_and_keeps_it_at_any_heading(
    tmp_path: Path,
) -> None:
    """lunar_jumping's launch (each hemi 80 N forward, 160 N up and +-52 N sideways in
    world y) is, at heading 0, the shared push with couple_n 52: the same spin. Turned
    90 deg, the world couple pushes along the tether and spins nothing, while couple_n
    still spins the robot at about 0.46 rad/s about the vertical."""
    world = (
        "{time_s: 0.0, hemi: both, force_a_n: [80, 52, 160], force_b_n: [80, -52, 160], "
        "duration_s: 0.6}"
    )
    spin = _launch_spin_rad_s(tmp_path, COUPLE, 0.0)
    # the shared push starts and ends by its own rule (any hemi in stance): 0.02 % apart
    np.testing.assert_allclose(spin, _launch_spin_rad_s(tmp_path, world, 0.0), rtol=1e-3)
    assert spin[2] == pytest.approx(0.46, abs=0.01) and np.linalg.norm(spin[:2]) < 1e-6
    turned = _launch_spin_rad_s(tmp_path, COUPLE, 90.0)
    # the forward push now meets the legs across the tether (0.03 rad/s of pitch)
    assert turned[2] == pytest.approx(spin[2], rel=0.1)
    assert abs(_launch_spin_rad_s(tmp_path, world, 90.0)[2]) < 1e-6
