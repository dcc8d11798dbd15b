"""Faults in scenarios, the library closed loop and campaigns (issue 31).

The closed loop: a joint fails in flight; the allocator finds it from the joint
states against its commands, holds its limb, mirrors it and plans the rest; with
``fault_handling: false`` nothing is found and nothing changes in the plan.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import yaml

from splitter_bringup.analysis.campaign import (
    PerturbationSpec,
    classify_flight,
    make_draw,
    scenario_document,
    scenario_for_draw,
)
from splitter_bringup.analysis.fault_draws import (
    FAULT_ROWS,
    REEL_LOCKED,
    detection_table,
    draw_fault,
    fault_detection,
    fault_row,
)
from splitter_bringup.run.library import run_closed_loop
from splitter_bringup.scenario.definition import ScenarioError, load_scenario
from splitter_model.faults import FAULT_CODES, JointFault
from splitter_model.joints import JOINT_INDEX, TETHER_INDEX, limb_joints
from splitter_model.redundancy import mirror_limb


def _tumble(faults, duration_s: float = 2.0, handling: bool = True):
    scenario = load_scenario("spin_stabilization", "mpc")
    return replace(scenario, faults=faults, duration_s=duration_s, fault_handling=handling)


def test_a_locked_knee_is_found_its_limb_held_and_mirrored() -> None:
    knee = JOINT_INDEX["hemi_a_y_pos_knee"]
    fault = JointFault("hemi_a_y_pos_knee", "locked", 0.5)
    series = run_closed_loop(_tumble((fault,)))
    x = series.extras
    t = series.t_s
    assert np.all(x["joint_fault"][t >= 0.5 + 1e-9, knee] == FAULT_CODES["locked"])
    assert np.all(x["joint_fault"][t < 0.5 - 1e-9, knee] == 0)
    found = fault_detection(
        t, series.joint_position, x["joint_command"], x["joint_detected"], fault
    )
    assert found.false_detections == 0
    assert 0.0 < found.latency_s <= 0.2  # [s] from the first commanded motion
    end = series.joint_position[-1]
    held, mirror = limb_joints(0), limb_joints(mirror_limb(0))
    assert np.allclose(end[mirror], end[held], atol=1e-6)  # the mirror copies it
    assert np.all(np.isfinite(series.angular_velocity_rad_s))


def test_a_z_limbs_limp_hip_pitch_settles_with_its_mirror_holding_its_pitch() -> None:
    """Seed 0's campaign draw 142: a z limb's hip pitch goes limp at 0.31 s. Its mirror
    keeps its hip pitch (``mirror_limb_command``) and the flight settles at 5.07 s; a
    mirror copying the swing left w_z at 0.38 rad/s at 7 s (and above 0.01 at 20 s)."""
    draw = make_draw(142, 1110119642, perturbation=PerturbationSpec(fault_time_max_s=2.0))
    assert draw.fault == JointFault("hemi_a_z_pos_hip_pitch", "limp", draw.fault.time_s)
    scenario = scenario_for_draw(load_scenario("spin_stabilization", "mpc"), draw, 7.0)
    series = run_closed_loop(scenario)
    outcome = classify_flight(series.t_s, series.angular_velocity_rad_s)
    assert outcome.success and outcome.settling_time_s < 6.0
    pitch = JOINT_INDEX["hemi_a_z_pos_hip_pitch"]
    mirror_pitch = limb_joints(mirror_limb(pitch // 3)).start + 1
    found = series.extras["joint_detected"][:, pitch].argmax()
    held = series.joint_position[found + 20 :, mirror_pitch]  # from 0.1 s after detection
    assert np.ptp(held) < 1e-3 < np.ptp(series.joint_position[found:, pitch])


def test_without_handling_nothing_is_found_and_the_plan_ignores_the_fault() -> None:
    fault = JointFault("hemi_a_y_pos_knee", "locked", 0.5)
    series = run_closed_loop(_tumble((fault,), handling=False))
    assert not series.extras["joint_detected"].any()
    end = series.joint_position[-1]
    assert not np.allclose(end[limb_joints(mirror_limb(0))], end[limb_joints(0)], atol=1e-3)


def test_a_nominal_flight_has_no_detection() -> None:
    series = run_closed_loop(_tumble((), duration_s=4.0))
    assert not series.extras["joint_detected"].any()


def test_random_faults_are_drawn_last_and_fill_the_rows_evenly() -> None:
    plain = make_draw(3, 1234, perturbation=PerturbationSpec())
    faulty = make_draw(3, 1234, perturbation=PerturbationSpec(fault_time_max_s=2.0))
    assert plain.fault is None
    assert replace(faulty, fault=None) == plain  # the rest of the draw is unchanged
    faults = [draw_fault(u) for u in np.random.default_rng(0).uniform(0.0, 1.0, (600, 3))]
    rows = [fault_row(f) for f in faults]
    counts = [rows.count(r) for r in FAULT_ROWS]
    assert min(counts) > 150
    assert all(0.0 <= f.time_s < 2.0 for f in faults)
    assert all(f.joint_index == TETHER_INDEX for f in faults if fault_row(f) == REEL_LOCKED)
    assert len({f.joint for f in faults if not f.is_reel}) == 24


def test_a_draws_fault_reaches_its_scenario_and_its_file(tmp_path) -> None:
    base = load_scenario("spin_stabilization", "mpc")
    draw = make_draw(0, 77, perturbation=PerturbationSpec(fault_time_max_s=2.0))
    assert scenario_for_draw(base, draw).faults == (draw.fault,)
    path = tmp_path / "draw.yaml"
    path.write_text(yaml.safe_dump(scenario_document(base, draw, 20.0)), encoding="utf-8")
    assert load_scenario(path).faults == (draw.fault,)


def test_detection_figures_of_a_synthetic_flight() -> None:
    t = np.arange(0.0, 2.0, 0.01)
    q = np.zeros((t.size, 25))
    command = np.zeros((t.size, 25))
    detected = np.zeros((t.size, 25))
    command[t >= 1.0, 2] = 0.1  # asked to move at 1.0 s, locked since 0.5 s
    detected[t >= 1.07, 2] = 1.0
    detected[t >= 1.5, 7] = 1.0  # a false one
    fault = JointFault("hemi_a_y_pos_knee", "locked", 0.5)
    found = fault_detection(t, q, command, detected, fault)
    assert found.first_motion_s == pytest.approx(1.0)
    assert found.latency_s == pytest.approx(0.07)
    assert found.false_detections == 1
    table = detection_table(["limb_locked"], [True], [found])
    assert table["limb_locked"]["detection_latency_max_s"] == pytest.approx(0.07)
    assert table["limb_locked"]["false_detections"] == 1
    nothing = fault_detection(t, q, q, np.zeros_like(q), fault)
    assert math.isnan(nothing.first_motion_s) and math.isnan(nothing.detected_s)


@pytest.mark.parametrize(
    ("faults", "message"),
    [
        ([{"joint": "elbow", "kind": "locked"}], r"faults\[0\]\.joint"),
        ([{"joint": "tether", "kind": "limp"}], r"faults\[0\]\.kind"),
        ([{"joint": "tether", "kind": "locked", "time_s": float("nan")}], r"faults\[0\]\.time_s"),
        ([{"joint": "tether", "kind": "locked", "when": 1}], "unknown field"),
        ("tether", "a list of faults"),
    ],
)
def test_bad_faults_in_a_scenario_name_the_field(tmp_path, faults, message) -> None:
    doc = dict(load_scenario("spin_stabilization").raw)
    doc["faults"] = faults
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(doc), encoding="utf-8")
    with pytest.raises(ScenarioError, match=message):
        load_scenario(path)


def test_fault_handling_must_be_a_boolean(tmp_path) -> None:
    doc = dict(load_scenario("spin_stabilization").raw)
    doc["fault_handling"] = "no"
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(doc), encoding="utf-8")
    with pytest.raises(ScenarioError, match="fault_handling"):
        load_scenario(path)
