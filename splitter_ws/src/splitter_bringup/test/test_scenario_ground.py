"""The scenario language's ground: slope, friction, steps; each bad field refused by name,
the initial pose and the pushes stated in the ground's frame, the campaign's terrains."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from splitter_bringup.analysis.jump_campaign import (
    JumpDrawResult,
    JumpRanges,
    LandingOutcome,
    binned_success,
    jump_scenario_document,
    make_jump_draw,
    scenario_for_jump_draw,
    tether_tilt_deg,
)
from splitter_bringup.run.library import run_closed_loop
from splitter_bringup.scenario.definition import ScenarioError, load_scenario, scenario_dir
from splitter_bringup.scenario.graph_config import simulator_parameters
from splitter_bringup.scenario.simulation import sim_config
from splitter_model.terrain import Step, Terrain

HEADER = (
    "duration_s: 1.0\ngravity: moon\nground_contact: true\ncompliant_legs: true\n"
    "initial: {position_m: [0, 0, 0.3]}\n"
    "jumps: [{time_s: 0, force_n: [160, 0, 320], duration_s: 0.6}]\n"
)


def _scenario(tmp_path: Path, ground: str) -> Path:
    path = tmp_path / "ground.yaml"
    path.write_text(HEADER + f"ground: {ground}\n")
    return path


def test_a_ground_reaches_the_simulator_in_both_backends(tmp_path: Path) -> None:
    scenario = load_scenario(
        _scenario(
            tmp_path,
            "{slope_deg: 5, slope_azimuth_deg: 90, friction_coefficient: 0.5, "
            "steps: [{x_m: [5, 6], y_m: [-2, 2], height_m: 0.15}]}",
        )
    )
    expected = Terrain(5.0, 90.0, (Step(5.0, 6.0, -2.0, 2.0, 0.15),))
    assert scenario.terrain == expected
    config = sim_config(scenario)
    assert config.terrain == expected
    assert config.friction_coefficient == 0.5
    params = simulator_parameters(scenario, real_time=False, rate_factor=1.0)
    assert params["ground_slope_deg"] == 5.0
    assert params["ground_steps_m"] == [5.0, 6.0, -2.0, 2.0, 0.15]
    assert params["friction_coefficient"] == 0.5


def test_the_initial_pose_and_the_pushes_are_the_ground_frames(tmp_path: Path) -> None:
    scenario = load_scenario(_scenario(tmp_path, "{slope_deg: 10}"))
    terrain = scenario.terrain
    frame = terrain.ground_frame()
    # 0.3 m above the base plane along its normal, aligned with it
    np.testing.assert_allclose(scenario.initial_position_m, 0.3 * np.array(terrain.normal))
    rotation = Rotation.from_euler("xyz", scenario.initial_orientation_euler_deg, degrees=True)
    np.testing.assert_allclose(rotation.as_matrix(), frame, atol=1e-12)
    np.testing.assert_allclose(scenario.jumps[0].force_n, frame @ [160.0, 0.0, 320.0])


@pytest.mark.parametrize(
    ("ground", "field"),
    [
        ("{slope_deg: 90}", r"ground\.slope_deg"),
        ("{slope_deg: 95}", r"ground\.slope_deg"),
        ("{slope_deg: .nan}", r"ground\.slope_deg"),
        ("{friction_coefficient: -0.1}", r"ground\.friction_coefficient"),
        ("{slope: 3}", r"ground\.slope"),
        ("{steps: [{x_m: [5, 6], y_m: [-2, 2], height_m: .nan}]}", r"ground\.steps\[0\]\.height_m"),
        ("{steps: [{x_m: [6, 5], y_m: [-2, 2], height_m: 0.1}]}", r"ground\.steps\[0\]\.x_m"),
        ("{steps: [{x_m: [5, 6], y_m: [-2, 2], high: 0.1}]}", r"ground\.steps\[0\]\.high"),
        # under the standing robot (the tether's half length plus the limbs: 3.4 m)
        ("{steps: [{x_m: [2, 6], y_m: [-2, 2], height_m: 0.1}]}", r"ground\.steps\[0\].*start"),
    ],
)
def test_a_bad_ground_is_refused_naming_its_field(tmp_path: Path, ground: str, field: str) -> None:
    with pytest.raises(ScenarioError, match=field):
        load_scenario(_scenario(tmp_path, ground))


def test_a_campaign_draw_flies_its_terrain_from_its_own_seed() -> None:
    base = load_scenario("lunar_jumping", "mpc")
    ranges = JumpRanges()
    draws = [make_jump_draw(i, 1000 + i, len(base.jumps), ranges) for i in range(200)]
    slopes = np.array([d.slope_deg for d in draws])
    heights = np.array([d.step_height_m for d in draws])
    assert 0.0 <= slopes.min() and slopes.max() <= 10.0 and slopes.std() > 2.0
    assert 0.0 <= heights.min() and heights.max() <= ranges.step_height_m
    assert heights.std() > 0.2 * ranges.step_height_m  # uniform: 0.29 of the range
    draw = draws[0]
    assert make_jump_draw(0, 1000, len(base.jumps), ranges) == draw  # replayable
    flown = scenario_for_jump_draw(base, draw)
    assert flown.terrain == draw.terrain
    assert flown.terrain.steps[0].x_min_m == draw.step_edge_m
    # the pushes are the ground frame's: the same angle to the ground as on level ground
    level = scenario_for_jump_draw(
        base, make_jump_draw(0, 1000, 2, JumpRanges(slope_deg=0.0, step_height_m=0.0))
    )
    normal = np.array(flown.terrain.normal)
    for tilted, flat in zip(flown.jumps, level.jumps, strict=True):
        assert np.dot(tilted.force_n, normal) == pytest.approx(flat.force_n[2])
    # no terrain drawn: the level world
    assert JumpRanges(slope_deg=0.0, step_height_m=0.0) and level.terrain.flat


def test_the_tether_tilt_is_measured_from_the_ground() -> None:
    terrain = Terrain(10.0, 0.0)
    xyzw = Rotation.from_matrix(terrain.ground_frame()).as_quat()
    aligned = np.array([[xyzw[3], *xyzw[:3]]])
    assert tether_tilt_deg(aligned)[0] == pytest.approx(10.0)  # from the level plane
    assert tether_tilt_deg(aligned, terrain.normal)[0] == pytest.approx(0.0, abs=1e-9)
    assert math.isfinite(float(tether_tilt_deg(aligned, terrain.normal)[0]))


def test_a_draws_scenario_file_flies_the_same_world(tmp_path: Path) -> None:
    """The file a campaign writes for a draw on terrain loads back as the world it flew."""
    variants = {v: load_scenario("lunar_jumping", v) for v in ("mpc", "open_loop")}
    draw = make_jump_draw(3, 4242, 2, JumpRanges(slope_deg=10.0, step_height_m=0.2))
    assert not draw.terrain.flat
    path = tmp_path / "draw.yaml"
    path.write_text(yaml.safe_dump(jump_scenario_document(variants, draw)))
    for name, base in variants.items():
        flown = scenario_for_jump_draw(base, draw)
        loaded = load_scenario(path, name)
        assert loaded.terrain == flown.terrain
        np.testing.assert_allclose(loaded.initial_position_m, flown.initial_position_m)
        np.testing.assert_allclose(
            loaded.initial_orientation_euler_deg, flown.initial_orientation_euler_deg, atol=1e-9
        )
        for a, b in zip(loaded.jumps, flown.jumps, strict=True):
            np.testing.assert_allclose(a.force_n, b.force_n, atol=1e-9)
            np.testing.assert_allclose(a.force_b_n, b.force_b_n, atol=1e-9)
        assert loaded.robot_errors == flown.robot_errors
        assert loaded.controller == flown.controller


def test_a_draws_scenario_file_keeps_a_jumps_couple(tmp_path: Path) -> None:
    """A push's couple_n (a spin whatever the heading) is in the draw's file, scaled by
    the draw's spin, so a replay flies the campaign's pushes."""
    source = yaml.safe_load((scenario_dir() / "lunar_jumping.yaml").read_text())
    source["jumps"][1]["couple_n"] = 52.0
    base_path = tmp_path / "lunar_jumping.yaml"
    base_path.write_text(yaml.safe_dump(source))
    variants = {v: load_scenario(base_path, v) for v in ("mpc", "open_loop")}
    for ranges in (JumpRanges(), JumpRanges(slope_deg=0.0, step_height_m=0.0)):
        draw = make_jump_draw(5, 99, 2, ranges)
        path = tmp_path / "draw.yaml"
        path.write_text(yaml.safe_dump(jump_scenario_document(variants, draw)))
        flown = scenario_for_jump_draw(variants["mpc"], draw)
        loaded = load_scenario(path, "mpc")
        assert [j.couple_n for j in loaded.jumps] == [j.couple_n for j in flown.jumps]
        assert loaded.jumps[1].couple_n == pytest.approx(52.0 * draw.spin_scale)


def test_the_terrain_factors_of_a_draw() -> None:
    draw = make_jump_draw(0, 7, 2, JumpRanges())
    factors = draw.factors()
    assert factors["step_edge_m"] == draw.step_edge_m
    expected = draw.slope_deg * math.cos(math.radians(draw.slope_azimuth_deg))
    assert factors["slope_along_path_deg"] == pytest.approx(expected)
    level = make_jump_draw(0, 7, 2, JumpRanges(slope_deg=0.0, step_height_m=0.0))
    assert math.isnan(level.factors()["step_edge_m"])  # no step, no edge


def test_success_against_a_factor_leaves_out_the_draws_without_it() -> None:
    ranges = JumpRanges()
    stepped = [make_jump_draw(i, 100 + i, 2, ranges) for i in range(6)]
    level = [make_jump_draw(9, 9, 2, JumpRanges(step_height_m=0.0))]
    results = [
        JumpDrawResult(d, {"mpc": LandingOutcome(success=i % 2 == 0, failure_mode=None)}, 1.0)
        for i, d in enumerate(stepped + level)
    ]
    _, rate, counts = binned_success(results, "mpc", "step_edge_m", bins=2)
    assert counts.sum() == len(stepped)
    assert np.nansum(rate * counts) == 3  # the three successes among the stepped draws


def _first_touchdown_speed_m_s(tmp_path: Path, ground: dict | None) -> float:
    """The fastest a hemi comes down [m/s] at its first touchdown after lunar_jumping's
    launch (open loop, the first flight only), over ``ground``."""
    doc = yaml.safe_load((scenario_dir() / "lunar_jumping.yaml").read_text())
    doc["duration_s"] = 6.0
    doc["jumps"] = doc["jumps"][:1]
    if ground is not None:
        doc["ground"] = ground
    path = tmp_path / f"launch_{len(list(tmp_path.iterdir()))}.yaml"
    path.write_text(yaml.safe_dump(doc))
    series = run_closed_loop(load_scenario(path, "open_loop"))
    force = np.linalg.norm(np.asarray(series.extras["contact_force_n"]), axis=2)
    velocity = np.asarray(series.velocity_m_s)
    t = np.asarray(series.t_s)
    flying = np.where(force.max(axis=1) < 1.0)[0]
    assert len(flying) > 0 and t[flying[0]] < 1.0  # it leaves the ground
    after = np.where((force.max(axis=1) > 1.0) & (np.arange(len(t)) > flying[0]))[0]
    assert len(after) > 0  # and comes down within the run
    return float(-velocity[after[0] - 1, 2])


def test_a_launch_down_a_slope_meets_it_no_faster_than_level_ground(tmp_path: Path) -> None:
    """The gait scales a downhill launch (splitter_mpc.core.gait.downhill_speed_scale):
    down 6 deg along the hop the drop adds ~0.4 m/s, which the 0.4 m stroke of a
    nominal 3.6 m/s touchdown (0.34 m used) does not have."""
    level = _first_touchdown_speed_m_s(tmp_path, None)
    downhill = _first_touchdown_speed_m_s(tmp_path, {"slope_deg": 6.0, "slope_azimuth_deg": 180.0})
    uphill = _first_touchdown_speed_m_s(tmp_path, {"slope_deg": 6.0, "slope_azimuth_deg": 0.0})
    assert 3.0 < level < 4.0
    assert downhill < level + 0.08
    assert uphill < level
