"""Gait phase machine: phase sequences, jump wrench, thrust timing, references, validation."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from splitter_model.model import PAPER_INITIAL_RADII_M, RobotModel, principal_inertia
from splitter_model.rotations import quaternion_to_matrix
from splitter_mpc.core.gait import (
    ANTIPARALLEL_TOLERANCE,
    LANDING_RATE_MAX_RAD_S,
    GaitConfig,
    GaitOutput,
    GaitPhase,
    GaitPhaseMachine,
    LandingTiming,
    PlannedJump,
    attitude_reference_at_stamp,
    downhill_speed_scale,
    gait_config_from_parameters,
    jump_plan_from_arrays,
    jump_wrench,
    momentum_aligned_attitude,
    predicted_touchdown_s,
    propagate_attitude,
    quaternion_multiply,
    scaled_jump,
    smallest_rotation,
    spin_couple_n,
    timed_landing_plan,
    timed_landing_reference,
)
from splitter_msgs_py import names

TICK_NS = 10_000_000  # [ns] control tick
MS = 1_000_000  # [ns]
IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])
MOON_G = 9.80665 / 6.0  # [m/s^2]
TOTAL_MASS_KG = 18.0  # [kg] 2 x (3.0 + 4 x 1.5)
RADIUS_X_M = 2.8  # [m]
STANCE_N = 20.0  # [N] a normal force well above the stance threshold
CONFIG_FILE = Path(__file__).resolve().parents[1] / "config" / "gait_phase_manager.yaml"


def jump(time_s: float, hemi: str = "auto", duration_s: float = 0.3, force=(40.0, 0.0, 40.0)):
    return PlannedJump(
        time_ns=round(time_s * 1e9),
        force_n=tuple(force),
        duration_ns=round(duration_s * 1e9),
        hemi=hemi,
    )


def tick(
    machine: GaitPhaseMachine,
    t_ns: int,
    *,
    normal=(0.0, 0.0),
    velocity=(0.0, 0.0, 0.0),
    rate=(0.0, 0.0, 0.0),
    orientation=IDENTITY,
    position=(0.0, 0.0, 0.45),
    radius_x_m: float = RADIUS_X_M,
    inertia=None,
) -> GaitOutput:
    return machine.update(t_ns, position, velocity, orientation, rate, radius_x_m, normal, inertia)


def axis_angle(axis, angle_rad: float) -> np.ndarray:
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    return np.concatenate(([math.cos(angle_rad / 2)], math.sin(angle_rad / 2) * axis))


def rotate(q: np.ndarray, v) -> np.ndarray:
    """q v q* by quaternion products (independent of the rotation matrix)."""
    conj = q * np.array([1.0, -1.0, -1.0, -1.0])
    return quaternion_multiply(quaternion_multiply(q, np.concatenate(([0.0], v))), conj)[1:]


def distinct(phases: list[GaitPhase]) -> list[GaitPhase]:
    return [p for i, p in enumerate(phases) if i == 0 or p != phases[i - 1]]


def test_phase_names_are_the_contract() -> None:
    assert tuple(p.value for p in GaitPhase) == names.GAIT_PHASES


def test_scripted_sequence_launch_flight_jump_flight_landing_landed() -> None:
    """Every phase in the paper's order on a script of debounced contact events.

    Touchdown needs 50 ms of stance without a break, lift-off more than 150 ms
    without stance (the defaults). The flickers at 0.6 s (30 ms of stance in the
    air) and at 1.4 s (100 ms without stance on the ground) are shorter: nothing
    changes.
    """
    config = GaitConfig(jumps=(jump(0.0, "b"), jump(2.0, "auto")), landed_dwell_s=0.3)
    machine = GaitPhaseMachine(config)
    log: list[GaitOutput] = []
    for k in range(450):
        t_ms = 10 * k
        if t_ms < 100 or t_ms >= 3000:
            normal = (STANCE_N, STANCE_N)
        elif 600 <= t_ms < 630 or (1000 <= t_ms < 2100 and not 1400 <= t_ms < 1500):
            normal = (STANCE_N, 0.0)
        else:
            normal = (0.0, 0.0)
        if 1000 <= t_ms < 2010:
            velocity = (1.0, 0.0, 0.0)  # standing after the touchdown, sliding on
        elif t_ms < 2600:
            velocity = (1.0, 0.0, 0.2)  # going up
        elif t_ms < 3200:
            velocity = (1.0, 0.0, -0.2)  # past the apex
        else:
            velocity = (0.0, 0.0, 0.0)  # at rest
        log.append(tick(machine, t_ms * MS, normal=normal, velocity=velocity))
    changes = [(out.t_ns // MS, out.phase, out.reason) for out in log if out.phase_changed]
    assert [(t_ms, phase) for t_ms, phase, _ in changes] == [
        (0, GaitPhase.LAUNCH),  # on the ground with a jump planned
        (250, GaitPhase.IN_FLIGHT),  # last stance at 90 ms: 160 ms > 150 ms later
        (1050, GaitPhase.JUMP),  # stance from 1000 ms, 50 ms without a break
        (2250, GaitPhase.IN_FLIGHT),  # last stance at 2090 ms; still going up
        (2600, GaitPhase.LANDING),  # the last jump is done and the robot descends
        (3500, GaitPhase.LANDED),  # on the ground at 3050 ms, at rest from 3200 ms + 300 ms
    ]
    words = ("start", "lift-off", "touchdown", "lift-off", "descending", "at rest")
    assert all(word in reason for (_, _, reason), word in zip(changes, words, strict=True))
    assert all(out.reason == "" for out in log if not out.phase_changed)
    # The debounced contact: on the ground from the start, off at 250 ms, on at 1050 ms
    # (not at 600 ms), on through the gap at 1.4 s, off at 2250 ms, on again at 3050 ms.
    assert log[0].on_ground
    flips = [
        out.t_ns // MS for prev, out in itertools.pairwise(log) if out.on_ground != prev.on_ground
    ]
    assert flips == [250, 1050, 2250, 3050]
    # Launch: hemi b pushes from 0 ms until the lift-off (before its 300 ms are over).
    # Second jump ("auto"): only hemi a is in stance at 2.0 s, so it pushes alone, until
    # the lift-off at 2250 ms (before 2.3 s).
    thrust_ms = [out.t_ns // MS for out in log if out.thrusting]
    assert thrust_ms == list(range(0, 250, 10)) + list(range(2000, 2250, 10))
    assert {out.pushing_hemi for out in log if out.thrusting and out.t_ns < 10**9} == {"b"}
    assert {out.pushing_hemi for out in log if out.thrusting and out.t_ns > 10**9} == {"a"}
    assert [out.jumps_done for out in log if out.t_ns // MS in (240, 250, 2240, 2250)] == [
        0,
        1,
        1,
        2,
    ]
    # The attitude reference: on the first tick and when Landing starts.
    assert [out.t_ns // MS for out in log if out.reference is not None] == [0, 2600]
    assert log[-1].phase == GaitPhase.LANDED and log[-1].jumps_done == 2


def test_flight_only_run_stays_in_flight_with_one_reference() -> None:
    config = GaitConfig(w_ref_rad_s=(0.0, 1.0, 0.0))
    machine = GaitPhaseMachine(config)
    q0 = axis_angle((1.0, 2.0, 3.0), 0.3)
    outputs = [
        tick(machine, k * TICK_NS, rate=(-0.3, -0.9, 0.9), orientation=q0, position=(0, 0, 10))
        for k in range(800)
    ]
    assert {out.phase for out in outputs} == {GaitPhase.IN_FLIGHT}
    assert all(not out.thrusting and not np.any(out.jump_force_n) for out in outputs)
    references = [out.reference for out in outputs if out.reference is not None]
    assert len(references) == 1
    assert references[0].stamp_ns == 0
    np.testing.assert_allclose(references[0].w_ref_rad_s, [0.0, 1.0, 0.0])
    np.testing.assert_allclose(references[0].q_ref_wxyz, q0)


def test_start_without_contact_is_in_flight_and_a_due_jump_waits_for_stance() -> None:
    machine = GaitPhaseMachine(GaitConfig(jumps=(jump(0.0, "a"),)))
    first = tick(machine, 0)
    assert first.phase == GaitPhase.IN_FLIGHT and not first.on_ground
    assert first.jump_waiting and not first.thrusting
    # In the air nothing is due: no thrust, no wait, whatever the contact forces say.
    for t_ms in range(10, 100, 10):
        out = tick(machine, t_ms * MS)
        assert out.phase == GaitPhase.IN_FLIGHT and not out.thrusting and not out.jump_waiting
    # Only hemi b touches down: after 50 ms of stance the touchdown is JUMP, but the
    # planned hemi a cannot push yet.
    for t_ms in range(100, 150, 10):
        out = tick(machine, t_ms * MS, normal=(0.0, STANCE_N))
        assert out.phase == GaitPhase.IN_FLIGHT and not out.thrusting and not out.on_ground
    for t_ms in range(150, 200, 10):
        out = tick(machine, t_ms * MS, normal=(0.0, STANCE_N))
        assert out.phase == GaitPhase.JUMP and out.on_ground and not out.thrusting
        assert out.phase_changed == (t_ms == 150)
    assert out.jump_waiting
    out = tick(machine, 200 * MS, normal=(STANCE_N, STANCE_N))
    assert out.thrusting and out.pushing_hemi == "a" and not out.jump_waiting


def test_auto_jump_is_shared_by_the_hemis_in_stance() -> None:
    q = axis_angle((0.0, 1.0, 0.0), math.radians(10.0))  # pitched: hemi a is the lower one
    force = np.array([40.0, 0.0, 40.0])  # [N]
    config = GaitConfig(jumps=(jump(0.0, "auto", force=force),))
    # Both in stance: each pushes half; the halves' moments about the COM cancel.
    out = tick(GaitPhaseMachine(config), 0, normal=(STANCE_N, STANCE_N), orientation=q)
    assert out.hemi_height_m[0] < out.hemi_height_m[1]
    assert out.pushing_hemi == "auto" and out.thrusting
    np.testing.assert_allclose(out.jump_force_n, force)
    np.testing.assert_allclose(out.jump_torque_nm, [0.0, 0.0, 0.0], atol=1e-12)
    # One in stance (even the higher one): it pushes alone, with its moment.
    for normal, hemi in (((0.0, STANCE_N), "b"), ((STANCE_N, 0.0), "a")):
        out = tick(GaitPhaseMachine(config), 0, normal=normal, orientation=q)
        assert out.pushing_hemi == hemi
        expected_force, expected_torque = jump_wrench(force, q, RADIUS_X_M, hemi)
        np.testing.assert_allclose(out.jump_force_n, expected_force)
        np.testing.assert_allclose(out.jump_torque_nm, expected_torque, atol=1e-12)
        assert np.linalg.norm(out.jump_torque_nm) > 100.0  # [Nm] 2.8 m x 40 N at least


def test_both_hemis_push_their_own_forces_once_both_are_in_stance() -> None:
    q = axis_angle((0.3, -0.5, 0.8), 0.4)
    force_a, force_b = np.array([10.0, 0.0, 200.0]), np.array([-10.0, 5.0, 120.0])  # [N]
    both = PlannedJump(0, tuple(force_a), 300 * MS, "both", tuple(force_b))
    machine = GaitPhaseMachine(GaitConfig(jumps=(both,)))
    # One hemi in stance: the launch waits for the other.
    out = tick(machine, 0, normal=(STANCE_N, 0.0), orientation=q)
    assert out.jump_waiting and not out.thrusting
    out = tick(machine, TICK_NS, normal=(STANCE_N, STANCE_N), orientation=q)
    assert out.pushing_hemi == "both" and out.thrusting
    lever_a = rotate(q, [RADIUS_X_M, 0.0, 0.0])  # p_a - p_com = -(p_b - p_com), world
    np.testing.assert_allclose(out.jump_force_n, force_a + force_b)
    np.testing.assert_allclose(
        out.jump_torque_nm, np.cross(lever_a, force_a) - np.cross(lever_a, force_b), atol=1e-12
    )


@pytest.mark.parametrize("hemi", ["auto", "both"])
@pytest.mark.parametrize("heading_deg", [0.0, 37.0, 90.0, 200.0])
def test_a_jump_couple_spins_about_the_vertical_whatever_the_heading(
    hemi: str, heading_deg: float
) -> None:
    """Each hemi pushes couple_n across the tether in the horizontal plane: the force is
    the plan's, the torque gains 2 r x F_side, 2 r_x couple_n cos(tilt) about +z, at any
    heading (and a roll about the level line when the tether is tilted)."""
    q = quaternion_multiply(
        axis_angle((0.0, 0.0, 1.0), math.radians(heading_deg)),
        axis_angle((0.0, 1.0, 0.0), math.radians(8.0)),  # standing on a slope
    )
    force = (80.0, 0.0, 160.0)  # [N]
    couple = 52.0  # [N]
    force_b = force if hemi == "both" else (0.0, 0.0, 0.0)
    plain = PlannedJump(0, force, 300 * MS, hemi, force_b)
    spun = PlannedJump(0, force, 300 * MS, hemi, force_b, couple_n=couple)
    outs = [
        tick(GaitPhaseMachine(GaitConfig(jumps=(j,))), 0, normal=(STANCE_N,) * 2, orientation=q)
        for j in (plain, spun)
    ]
    np.testing.assert_allclose(outs[1].jump_force_n, outs[0].jump_force_n, atol=1e-12)
    added = outs[1].jump_torque_nm - outs[0].jump_torque_nm
    tether = rotate(q, [1.0, 0.0, 0.0])
    side = spin_couple_n(q, couple)
    assert abs(side @ tether) < 1e-12 and side[2] == 0.0  # across the tether, horizontal
    assert np.linalg.norm(side) == pytest.approx(couple)
    np.testing.assert_allclose(added, 2.0 * np.cross(RADIUS_X_M * tether, side), atol=1e-9)
    lever = RADIUS_X_M * math.hypot(tether[0], tether[1])  # [m] horizontal, to each hemi
    assert added[2] == pytest.approx(2.0 * lever * couple)  # counter-clockwise from above


def test_a_couple_needs_both_hemis_and_a_finite_size() -> None:
    with pytest.raises(ValueError, match="couple_n"):
        GaitConfig(jumps=(PlannedJump(0, (0.0, 0.0, 1.0), MS, "a", couple_n=10.0),))
    with pytest.raises(ValueError, match="couple_n"):
        GaitConfig(jumps=(PlannedJump(0, (0.0, 0.0, 1.0), MS, "auto", couple_n=math.nan),))
    with pytest.raises(ValueError, match="jump_couples_n"):
        jump_plan_from_arrays([0.0], [0.0, 0.0, 1.0], [0.1], ["auto"], couples_n=[1.0, 2.0])
    with pytest.raises(ValueError, match="jump_couples_n"):
        jump_plan_from_arrays([0.0], [0.0, 0.0, 1.0], [0.1], ["auto"], couples_n=[math.inf])
    plan = jump_plan_from_arrays([0.0], [0.0, 0.0, 1.0], [0.1], ["auto"], couples_n=[52.0])
    assert plan[0].couple_n == 52.0


def test_a_force_for_hemi_b_is_for_a_push_by_both_only() -> None:
    with pytest.raises(ValueError, match="force_b_n"):
        GaitConfig(jumps=(PlannedJump(0, (0.0, 0.0, 1.0), MS, "a", (0.0, 0.0, 1.0)),))
    with pytest.raises(ValueError, match="jump_forces_b_n"):
        jump_plan_from_arrays([0.0], [0.0, 0.0, 1.0], [0.1], ["both"], [0.0, 1.0])


def test_the_predicted_touchdown_is_the_ballistic_fall_to_the_legs_height() -> None:
    # From 4.6 m up at rest on the Moon to 0.6 m: sqrt(2 x 4 / 1.62) = 2.222 s.
    assert predicted_touchdown_s(4.6, 0.0, MOON_G, 0.6) == pytest.approx(math.sqrt(8.0 / MOON_G))
    # Rising at 3.6 m/s from 0.6 m: back at 0.6 m after 2 v / g.
    assert predicted_touchdown_s(0.6 + 1e-12, 3.6, MOON_G, 0.6) == pytest.approx(7.2 / MOON_G)
    assert predicted_touchdown_s(0.5, -1.0, MOON_G, 0.6) == 0.0  # already there
    assert predicted_touchdown_s(2.6, -2.0, 0.0, 0.6) == pytest.approx(1.0)  # no gravity
    assert predicted_touchdown_s(2.6, 0.5, 0.0, 0.6) == math.inf


def test_the_stance_shape_is_asked_for_within_the_lead_of_the_touchdown() -> None:
    config = GaitConfig(jumps=(jump(0.0, "auto"), jump(5.0, "auto")), stance_lead_s=0.5)
    machine = GaitPhaseMachine(config, gravity_m_s2=MOON_G)
    out = tick(machine, 0, normal=(STANCE_N, STANCE_N))
    assert out.stance_shape and out.touchdown_in_s == 0.0  # on the ground: legs
    t = TICK_NS
    for _ in range(40):  # lift-off
        out = tick(machine, t, position=(0.0, 0.0, 2.0), velocity=(0.0, 0.0, 3.0))
        t += TICK_NS
    assert out.phase == GaitPhase.IN_FLIGHT and not out.stance_shape
    # Falling at 1 m/s with the hemi bodies 1.0 m up: 0.4 m to go, 0.34 s: within the lead.
    out = tick(machine, t, position=(0.0, 0.0, 1.0), velocity=(0.0, 0.0, -1.0))
    assert out.touchdown_in_s == pytest.approx(predicted_touchdown_s(1.0, -1.0, MOON_G, 0.6))
    assert out.touchdown_in_s < 0.5 and out.stance_shape
    # Higher up (2 s to go): the limbs are the MPC's.
    out = tick(machine, t + TICK_NS, position=(0.0, 0.0, 3.0), velocity=(0.0, 0.0, -1.0))
    assert out.touchdown_in_s > 1.0 and not out.stance_shape


@pytest.mark.parametrize("hemi", ["a", "b"])
def test_jump_torque_is_lever_cross_force_for_a_rotated_body(hemi: str) -> None:
    q = axis_angle((0.3, -0.5, 0.8), 1.1)
    radius_x = 1.7  # [m]
    force = np.array([40.0, -5.0, 40.0])  # [N]
    machine = GaitPhaseMachine(GaitConfig(jumps=(jump(0.0, hemi, force=force),)))
    out = tick(machine, 0, normal=(STANCE_N, STANCE_N), orientation=q, radius_x_m=radius_x)
    sign = names.HEMI_SIGNS[hemi]
    lever = rotate(q, [sign * radius_x, 0.0, 0.0])  # p_hemi - p_com, world
    np.testing.assert_allclose(out.jump_force_n, force)
    np.testing.assert_allclose(out.jump_torque_nm, np.cross(lever, force), atol=1e-12)
    assert abs(out.jump_torque_nm @ force) < 1e-9
    assert abs(out.jump_torque_nm @ lever) < 1e-9


def test_lunar_launch_through_hemi_b_spins_about_plus_y() -> None:
    # Level body, hemi b at (-2.8, 0, 0), F = (40, 0, 40) N: tau = (0, 2.8 * 40, 0) Nm.
    force, torque = jump_wrench((40.0, 0.0, 40.0), IDENTITY, 2.8, "b")
    np.testing.assert_allclose(force, [40.0, 0.0, 40.0])
    np.testing.assert_allclose(torque, [0.0, 112.0, 0.0], atol=1e-12)


def test_wrench_follows_the_attitude_during_the_thrust() -> None:
    machine = GaitPhaseMachine(GaitConfig(jumps=(jump(0.0, "b", duration_s=0.5),)))
    for k in range(60):  # hemi b pushes over its stroke while the body pitches
        q = axis_angle((0.0, 1.0, 0.0), 0.01 * k)
        out = tick(machine, k * TICK_NS, normal=(0.0, STANCE_N), orientation=q)
        assert out.thrusting == (k < 50)  # the planned 0.5 s
        if out.thrusting:
            np.testing.assert_allclose(
                out.jump_torque_nm,
                np.cross(rotate(q, [-RADIUS_X_M, 0, 0]), [40, 0, 40]),
                atol=1e-9,
            )
    assert out.jumps_done == 1 and out.phase == GaitPhase.LAUNCH


def test_thrust_ends_at_the_lift_off() -> None:
    """In stance on the first tick only: the thrust lasts until the debounced lift-off."""
    machine = GaitPhaseMachine(GaitConfig(jumps=(jump(0.0, "b", duration_s=0.5),)))
    log = [
        tick(
            machine,
            k * TICK_NS,
            normal=(0.0, STANCE_N) if k == 0 else (0.0, 0.0),
            velocity=(0.5, 0.0, 1.0),  # going up
        )
        for k in range(50)
    ]
    # Last stance at 0 ms; lift-off once more than 150 ms have passed without it.
    assert [out.t_ns // MS for out in log if out.thrusting] == list(range(0, 160, 10))
    lift_off = log[16]
    assert lift_off.t_ns == 160 * MS and lift_off.phase == GaitPhase.IN_FLIGHT
    assert lift_off.phase_changed and not lift_off.on_ground and lift_off.jumps_done == 1
    assert all(out.phase == GaitPhase.IN_FLIGHT and not out.jump_waiting for out in log[16:])


@pytest.mark.parametrize(
    ("time_s", "duration_s", "first_ms", "n_ticks"),
    [(0.0, 0.6, 0, 60), (0.015, 0.6, 20, 60), (5.0, 0.6, 5000, 60), (1.0, 0.605, 1000, 61)],
)
def test_thrust_lasts_the_planned_duration_on_the_tick_grid(
    time_s: float, duration_s: float, first_ms: int, n_ticks: int
) -> None:
    force = np.array([40.0, 0.0, 40.0])
    machine = GaitPhaseMachine(GaitConfig(jumps=(jump(time_s, "b", duration_s, force),)))
    thrust_ms = []
    impulse = np.zeros(3)  # [N s] the simulator holds each command for one tick
    for k in range(700):
        out = tick(machine, k * TICK_NS, normal=(0.0, STANCE_N))
        if out.thrusting:
            thrust_ms.append(10 * k)
            impulse += out.jump_force_n * TICK_NS / 1e9
    assert thrust_ms == [first_ms + 10 * i for i in range(n_ticks)]
    np.testing.assert_allclose(impulse, force * n_ticks * 0.01, rtol=1e-12)


def test_touchdown_before_the_next_jump_waits_and_a_bounce_is_flight() -> None:
    config = GaitConfig(jumps=(jump(0.0, "b"), jump(3.0, "auto")))
    machine = GaitPhaseMachine(config)
    up = (0.0, 0.0, 1.0)  # [m/s]

    def phase_at(t_ms: int, normal=(0.0, 0.0)) -> GaitPhase:
        return tick(machine, t_ms * MS, normal=normal, velocity=up).phase

    # Launch thrust in stance (0-40 ms), then in the air; lift-off 160 ms after the last
    # stance.
    phases = {t: phase_at(t, (0.0, STANCE_N) if t < 50 else (0.0, 0.0)) for t in range(0, 600, 10)}
    assert phases[190] == GaitPhase.LAUNCH and phases[200] == GaitPhase.IN_FLIGHT
    # 30 ms of stance in the air (shorter than the 50 ms touchdown debounce): still flying.
    assert {phase_at(t, (STANCE_N, 0.0)) for t in range(600, 640, 10)} == {GaitPhase.IN_FLIGHT}
    assert {phase_at(t) for t in range(640, 1000, 10)} == {GaitPhase.IN_FLIGHT}
    # Touchdown on hemi a: JUMP after 50 ms of stance; it waits there for the next jump.
    assert [phase_at(t, (STANCE_N, 0.0)) for t in range(1000, 1060, 10)] == [
        GaitPhase.IN_FLIGHT
    ] * 5 + [GaitPhase.JUMP]
    assert {phase_at(t, (STANCE_N, 0.0)) for t in range(1060, 1200, 10)} == {GaitPhase.JUMP}
    # No stance for 100 ms (shorter than the 150 ms lift-off debounce): still on the ground.
    assert {phase_at(t) for t in range(1200, 1300, 10)} == {GaitPhase.JUMP}
    assert {phase_at(t, (STANCE_N, 0.0)) for t in range(1300, 1500, 10)} == {GaitPhase.JUMP}
    # A real bounce: last stance at 1490 ms, lift-off once more than 150 ms have passed.
    bounce = [tick(machine, t * MS, velocity=up) for t in range(1500, 1700, 10)]
    assert [out.t_ns // MS for out in bounce if out.phase_changed] == [1650]
    assert bounce[15].phase == GaitPhase.IN_FLIGHT and "lift-off" in bounce[15].reason
    assert all(out.phase == GaitPhase.JUMP for out in bounce[:15])
    # Back on both hemis before the next jump is due: JUMP again, and the thrust waits
    # for its time.
    log = [tick(machine, t * MS, normal=(STANCE_N, STANCE_N)) for t in range(2000, 3100, 10)]
    assert [out.t_ns // MS for out in log if out.phase_changed] == [2050]
    assert log[5].phase == GaitPhase.JUMP and "touchdown" in log[5].reason
    assert [out.t_ns // MS for out in log if out.thrusting] == list(range(3000, 3100, 10))
    assert {out.pushing_hemi for out in log if out.thrusting} == {"auto"}
    assert log[-1].jumps_done == 1  # the second thrust is still running


def test_landed_needs_both_hemis_at_rest_for_the_dwell_and_is_final() -> None:
    config = GaitConfig(
        landed_speed_m_s=0.05,
        landed_angular_speed_rad_s=0.05,
        landed_dwell_s=0.2,
    )
    machine = GaitPhaseMachine(config)
    first = tick(machine, 0, velocity=(0.0, 0.0, -0.5))
    assert first.phase == GaitPhase.IN_FLIGHT
    # No jump planned: IN_FLIGHT until the first touchdown (50 ms of stance), then LANDING.
    out = [
        tick(machine, t * MS, normal=(STANCE_N, 0), velocity=(0.3, 0, 0)) for t in range(10, 70, 10)
    ]
    assert [o.phase for o in out] == [GaitPhase.IN_FLIGHT] * 5 + [GaitPhase.LANDING]
    assert "touchdown" in out[-1].reason
    # At rest on one hemi only: not LANDED, however long.
    still = {"rate": (0.0, 0.04, 0.0)}  # below the 0.05 rad/s threshold
    out = [tick(machine, t * MS, normal=(STANCE_N, 0), **still) for t in range(70, 600, 10)]
    assert {o.phase for o in out} == {GaitPhase.LANDING}
    # On both hemis: the dwell starts at 600 ms; a disturbance at 700 ms restarts it.
    both = (STANCE_N, STANCE_N)
    out = [tick(machine, t * MS, normal=both, **still) for t in range(600, 700, 10)]
    out.append(tick(machine, 700 * MS, normal=both, rate=(0.0, 0.06, 0.0)))
    out += [tick(machine, t * MS, normal=both, **still) for t in range(710, 1000, 10)]
    assert [o.t_ns // MS for o in out if o.phase_changed] == [910]  # 710 ms + 200 ms
    assert out[-1].phase == GaitPhase.LANDED and "at rest" in out[31].reason
    # LANDED is final: disturbed, moving, even off the ground for a second, it stays.
    after = [
        tick(machine, t * MS, velocity=(0.5, 0.0, 0.5), rate=(0.0, 2.0, 0.0))
        for t in range(1000, 2000, 10)
    ]
    assert all(o.phase == GaitPhase.LANDED and not o.phase_changed for o in after)
    assert all(o.reference is None for o in after)
    assert after[0].on_ground and not after[-1].on_ground  # the lift-off happened


def test_vertical_hopper_closed_loop_jumps_twice_and_comes_to_rest() -> None:
    """Point mass on legs and a spring-damper ground under lunar gravity, driven by the machine.

    As in the simulator, the thrust acts while the legs reach the ground (0.4 m of
    stroke above the unloaded contact) and is reported as ground reaction. Launch
    at 0.5 s, touch down and wait on the ground for the second jump at 4 s, land
    after its apex and come to rest: every phase in the paper's order.
    """
    stiffness, damping = 20000.0, 600.0  # [N/m], [N s/m] ground, per hemi
    stroke = 0.4  # [m] the legs' reach
    dt_ns = 5 * MS  # [ns] sim step; the machine runs every other step
    z0 = 0.45  # [m] centre of mass height when the contact spring is unloaded
    z_rest = z0 - TOTAL_MASS_KG * MOON_G / (2 * stiffness)
    z, vz = z_rest, 0.0  # resting on the ground
    thrust = (0.0, 0.0, 60.0)  # [N]
    config = GaitConfig(
        jumps=(jump(0.5, "auto", 0.6, thrust), jump(4.0, "auto", 0.6, thrust)),
        landed_dwell_s=0.5,
    )
    machine = GaitPhaseMachine(config)
    force_z = 0.0  # [N] the thrust commanded on the last tick
    log: list[tuple[GaitOutput, float]] = []  # with the vertical velocity the machine saw
    peak_z = z
    raw_stance: list[bool] = []
    for step in range(3000):  # 15 s
        t_ns = step * dt_ns
        penetration = max(0.0, z0 - z)
        per_hemi = max(0.0, stiffness * penetration - damping * vz) if penetration > 0 else 0.0
        legs = force_z / 2.0 if z < z0 + stroke else 0.0  # [N] per hemi, thrust in reach
        if t_ns % TICK_NS == 0:
            normal = (per_hemi + legs, per_hemi + legs)
            out = machine.update(
                t_ns, (0, 0, z), (0, 0, vz), IDENTITY, (0, 0, 0), RADIUS_X_M, normal
            )
            force_z = out.jump_force_n[2]
            legs = force_z / 2.0 if z < z0 + stroke else 0.0
            log.append((out, vz))
            raw_stance.append(any(out.stance))
        accel = (2 * (legs + per_hemi)) / TOTAL_MASS_KG - MOON_G
        vz += accel * dt_ns / 1e9
        z += vz * dt_ns / 1e9
        peak_z = max(peak_z, z)
    outputs = [out for out, _ in log]
    assert [out.phase for out in outputs if out.phase_changed] == [
        GaitPhase.LAUNCH,
        GaitPhase.IN_FLIGHT,
        GaitPhase.JUMP,
        GaitPhase.IN_FLIGHT,
        GaitPhase.LANDING,
        GaitPhase.LANDED,
    ]
    # Both thrusts last their planned 0.6 s: the legs reach the ground throughout.
    thrust_ms = [out.t_ns // MS for out in outputs if out.thrusting]
    assert thrust_ms == list(range(500, 1100, 10)) + list(range(4000, 4600, 10))
    assert {out.pushing_hemi for out in outputs if out.thrusting} == {"auto"}
    # 60 N for 0.6 s on 18 kg against 29.2 N: the robot flies, its legs clear of the ground.
    assert peak_z > z0 + stroke + 0.15
    assert machine.jumps_done == 2
    # Contact events on the debounce: each lift-off 160 ms after the last stance (more
    # than 150 ms), each touchdown after 50 ms of stance without a break.
    streaks = []  # (first, last) tick index of each run of raw stance
    for k, stance in enumerate(raw_stance):
        if stance and (k == 0 or not raw_stance[k - 1]):
            streaks.append([k, k])
        elif stance:
            streaks[-1][1] = k
    for k, out in enumerate(outputs[1:], start=1):
        if out.on_ground and not outputs[k - 1].on_ground:  # touchdown
            first = next(a for a, b in streaks if a <= k <= b)
            assert k - first == 5
        elif not out.on_ground and outputs[k - 1].on_ground:  # lift-off
            last = max(b for _, b in streaks if b < k)
            assert k - last == 16
    # The spring ground bounces the robot back up after 40 ms of contact, before the
    # touchdown debounce is over: neither bounce (after each flight) changes the phase.
    bounces = [(a, b) for a, b in streaks if b + 1 < len(log) and b - a < 5]
    assert len(bounces) == 2
    for a, b in bounces:
        assert not any(out.phase_changed or out.on_ground for out in outputs[a : b + 2])
    touchdown = next(out for out in outputs if out.phase == GaitPhase.JUMP)
    assert 1100 < touchdown.t_ns // MS < 4000 and any(touchdown.stance)
    # Landing once the centre of mass descends after the last jump: at the apex.
    k_landing = next(k for k, (out, _) in enumerate(log) if out.phase == GaitPhase.LANDING)
    assert log[k_landing][1] <= 0.0 < log[k_landing - 1][1]
    assert not log[k_landing][0].on_ground  # in the air
    # LANDED after the 500 ms dwell at rest on both hemis; at rest on the ground spring.
    k_landed = next(k for k, out in enumerate(outputs) if out.phase == GaitPhase.LANDED)
    assert all(all(out.stance) and out.on_ground for out in outputs[k_landed - 50 : k_landed])
    assert not outputs[k_landed - 51].on_ground
    assert abs(z - z_rest) < 1e-3
    assert all(out.phase == GaitPhase.LANDED for out in outputs[k_landed:])


def test_attitude_references_first_tick_and_landing() -> None:
    q0 = axis_angle((0.0, 0.0, 1.0), 0.2)
    config = GaitConfig(
        jumps=(jump(0.0, "auto", 0.1),),
        w_ref_rad_s=(0.0, 1.0, 0.0),
        landing_w_ref_rad_s=(0.0, 0.0, 0.0),
        attitude_reference="integrate_w_ref",
    )
    machine = GaitPhaseMachine(config)
    out = tick(machine, 0, normal=(STANCE_N, STANCE_N), orientation=q0)
    assert out.reference is not None and out.reference.propagate
    np.testing.assert_allclose(out.reference.w_ref_rad_s, [0.0, 1.0, 0.0])
    np.testing.assert_allclose(out.reference.q_ref_wxyz, q0)
    # pi seconds at 1 rad/s about body y: q0 (x) (cos pi/2, 0, sin pi/2, 0).
    np.testing.assert_allclose(
        out.reference.attitude_at(round(math.pi * 1e9)),
        quaternion_multiply(q0, [0.0, 0.0, 1.0, 0.0]),
        atol=1e-9,
    )
    q_landing = axis_angle((1.0, 0.0, 0.0), 0.5)
    outputs = [tick(machine, k * TICK_NS, orientation=q_landing) for k in range(1, 20)]
    landing = [out for out in outputs if out.reference is not None]
    assert len(landing) == 1 and landing[0].phase == GaitPhase.LANDING
    # The thrust is over at 100 ms; the lift-off (last stance at 0 ms) comes at 160 ms
    # with the centre of mass not rising: straight to Landing.
    assert landing[0].t_ns == 160 * MS and "descending" in landing[0].reason
    np.testing.assert_allclose(landing[0].reference.w_ref_rad_s, [0.0, 0.0, 0.0])
    np.testing.assert_allclose(landing[0].reference.q_ref_wxyz, q_landing)
    np.testing.assert_allclose(machine.reference.attitude_at(10**10), q_landing)


def test_a_jump_that_never_leaves_the_ground_lands_after_the_lift_off_debounce() -> None:
    machine = GaitPhaseMachine(GaitConfig(jumps=(jump(0.0, "auto", 0.1),)))
    log = [tick(machine, k * TICK_NS, normal=(STANCE_N, STANCE_N)) for k in range(40)]
    assert [out.t_ns // MS for out in log if out.thrusting] == list(range(0, 100, 10))
    # The thrust ends at 100 ms; still on the ground more than 150 ms later: Landing.
    assert [(out.t_ns // MS, out.phase) for out in log if out.phase_changed] == [
        (0, GaitPhase.LAUNCH),
        (260, GaitPhase.LANDING),
    ]
    assert "without leaving the ground" in log[26].reason
    assert log[26].reference is not None and log[26].on_ground


def test_lift_off_after_the_last_jump_while_rising_is_flight_then_landing_at_the_apex() -> None:
    machine = GaitPhaseMachine(GaitConfig(jumps=(jump(0.0, "b", 0.1),)))
    log = []
    for k in range(60):
        normal = (0.0, STANCE_N) if k < 5 else (0.0, 0.0)
        vz = 1.0 - 0.04 * k  # [m/s] the apex at 250 ms
        log.append(tick(machine, k * TICK_NS, normal=normal, velocity=(0.0, 0.0, vz)))
    assert [(out.t_ns // MS, out.phase) for out in log if out.phase_changed] == [
        (0, GaitPhase.LAUNCH),
        (200, GaitPhase.IN_FLIGHT),  # last stance at 40 ms; the thrust ended at 100 ms
        (250, GaitPhase.LANDING),  # v_z = 0: descending
    ]


def test_initial_mode_holds_the_first_attitude() -> None:
    q0 = axis_angle((1.0, 1.0, 0.0), 0.4)
    machine = GaitPhaseMachine(GaitConfig(attitude_reference="initial"))
    reference = tick(machine, 0, orientation=q0, position=(0, 0, 10)).reference
    assert reference is not None and not reference.propagate
    np.testing.assert_allclose(reference.attitude_at(5 * 10**9), q0)


# --- the momentum-aligned attitude reference -------------------------------------------------
# Table II: w0 = [0.5, -0.5, 0.5] rad/s, attitude [5, 5, 15] deg (extrinsic x, y, z), radii
# [2.8, 0.2, 0.2] m; the body momentum I w0 is 135 deg from +body y.
TABLE_II_Q0 = quaternion_multiply(
    axis_angle((0, 0, 1), math.radians(15.0)),
    quaternion_multiply(
        axis_angle((0, 1, 0), math.radians(5.0)), axis_angle((1, 0, 0), math.radians(5.0))
    ),
)
TABLE_II_W0 = np.array([0.5, -0.5, 0.5])  # [rad/s]
TABLE_II_I0 = principal_inertia(RobotModel(), PAPER_INITIAL_RADII_M)  # [kg m^2]
E_Y = np.array([0.0, 1.0, 0.0])


def world_momentum(q, w, inertia) -> np.ndarray:
    """H = q (I w) q* by quaternion products [kg m^2/s]."""
    return rotate(np.asarray(q, dtype=float), np.asarray(inertia) * np.asarray(w))


def rotation_angle_and_axis(q) -> tuple[float, np.ndarray]:
    q = np.asarray(q, dtype=float) * (1.0 if q[0] >= 0.0 else -1.0)
    return 2.0 * math.atan2(np.linalg.norm(q[1:]), q[0]), q[1:] / np.linalg.norm(q[1:])


def test_smallest_rotation_closed_forms() -> None:
    x, y, z = np.eye(3)
    np.testing.assert_array_equal(smallest_rotation(x, x, z), IDENTITY)
    # x onto y: a quarter turn about z
    np.testing.assert_allclose(smallest_rotation(x, y, z), axis_angle(z, math.pi / 2), atol=1e-16)
    # x onto -x: the half turn about the part of the hint perpendicular to x
    np.testing.assert_array_equal(smallest_rotation(x, -x, z), [0.0, 0.0, 0.0, 1.0])
    np.testing.assert_allclose(smallest_rotation(x, -x, (3.0, 0.0, 4.0)), [0, 0, 0, 1], atol=1e-16)
    with pytest.raises(ValueError, match="half_turn_axis"):
        smallest_rotation(x, -x, (2.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="to_unit"):
        smallest_rotation(x, (0.0, 2.0, 0.0), z)


def test_smallest_rotation_takes_a_onto_b_about_their_normal() -> None:
    rng = np.random.default_rng(3)
    for _ in range(200):
        a, b = (v / np.linalg.norm(v) for v in rng.normal(size=(2, 3)))
        q = smallest_rotation(a, b, rng.normal(size=3))
        assert abs(np.linalg.norm(q) - 1.0) < 1e-15
        np.testing.assert_allclose(rotate(q, a), b, atol=1e-12)
        angle, axis = rotation_angle_and_axis(q)
        # the smallest: angle between a and b, about an axis perpendicular to both
        assert angle == pytest.approx(math.acos(np.clip(a @ b, -1.0, 1.0)), abs=1e-12)
        assert abs(axis @ a) < 1e-12 and abs(axis @ b) < 1e-12
    # nearly opposite, either side of the tolerance: still onto b to the stated ~2e-8 rad
    a = np.array([1.0, 0.0, 0.0])
    for gap in (0.5 * ANTIPARALLEL_TOLERANCE, 2.0 * ANTIPARALLEL_TOLERANCE, 1e-6):
        b = np.array([-math.cos(gap), math.sin(gap), 0.0])
        assert np.linalg.norm(rotate(smallest_rotation(a, b, (0, 0, 1)), a) - b) < 2e-8


def test_momentum_aligned_reference_has_body_y_along_the_world_momentum() -> None:
    """Table II: R(q_ref) e = H / |H| with H conserved; the smallest turn, 135 deg about x."""
    q_ref = momentum_aligned_attitude(TABLE_II_Q0, TABLE_II_W0, TABLE_II_I0, (0.0, 1.0, 0.0))
    momentum = world_momentum(TABLE_II_Q0, TABLE_II_W0, TABLE_II_I0)
    np.testing.assert_allclose(rotate(q_ref, E_Y), momentum / np.linalg.norm(momentum), atol=1e-12)
    # +H, not -H: in the reference's body frame the momentum is +|H| e_y (w_ref's sense)
    conj = q_ref * np.array([1.0, -1.0, -1.0, -1.0])
    np.testing.assert_allclose(rotate(conj, momentum), np.linalg.norm(momentum) * E_Y, atol=1e-9)
    q_align = quaternion_multiply(q_ref, TABLE_II_Q0 * np.array([1.0, -1.0, -1.0, -1.0]))
    angle, axis = rotation_angle_and_axis(q_align)
    h = TABLE_II_I0 * TABLE_II_W0
    assert angle == pytest.approx(math.acos(h[1] / np.linalg.norm(h)), abs=1e-12)  # 135.0 deg
    assert math.degrees(angle) == pytest.approx(135.0, abs=0.2)
    assert abs(axis @ rotate(TABLE_II_Q0, E_Y)) < 1e-12 and abs(axis @ momentum) < 1e-12
    # I w0 is nearly in the body y-z plane: the turn is nearly about body x
    assert abs(axis @ rotate(TABLE_II_Q0, (1.0, 0.0, 0.0))) > 0.999


def test_momentum_aligned_reference_in_the_closed_form_cases() -> None:
    q = axis_angle((0.3, -1.0, 2.0), 0.7)
    inertia = (0.5, 140.0, 141.0)
    w_ref = (0.0, 1.0, 0.0)
    # spinning about +y already: nothing to turn
    np.testing.assert_allclose(momentum_aligned_attitude(q, (0, 0.8, 0), inertia, w_ref), q, 1e-15)
    # about -y: the half turn about the body x axis (the body axis most perpendicular to y)
    q_ref = momentum_aligned_attitude(q, (0.0, -0.8, 0.0), inertia, w_ref)
    np.testing.assert_allclose(q_ref, quaternion_multiply(q, [0.0, 1.0, 0.0, 0.0]), atol=1e-15)
    np.testing.assert_allclose(rotate(q_ref, E_Y), -rotate(q, E_Y), atol=1e-15)
    # no axis (w_ref = 0) or no momentum (w = 0): the measured attitude, as given
    for w, ref in (((0.1, 0.2, 0.3), (0.0, 0.0, 0.0)), ((0.0, 0.0, 0.0), w_ref)):
        np.testing.assert_array_equal(momentum_aligned_attitude(q, w, inertia, ref), q)
    # the sense of w_ref decides +H: w_ref = -y puts body y along -H
    q_minus = momentum_aligned_attitude(q, (0.2, 0.5, -0.1), inertia, (0.0, -2.0, 0.0))
    momentum = world_momentum(q, (0.2, 0.5, -0.1), inertia)
    np.testing.assert_allclose(rotate(q_minus, -E_Y), momentum / np.linalg.norm(momentum), 1e-12)


@pytest.mark.parametrize(
    ("w", "inertia", "name"),
    [
        ((math.nan, 0.0, 0.0), (1.0, 1.0, 1.0), "angular_velocity_rad_s"),
        ((0.0, 1.0, 0.0), (1.0, 0.0, 1.0), "principal_inertia_kg_m2"),
        ((0.0, 1.0, 0.0), (1.0, 1.0), "principal_inertia_kg_m2"),
    ],
)
def test_momentum_aligned_reference_names_a_bad_input(w, inertia, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        momentum_aligned_attitude(IDENTITY, w, inertia, (0.0, 1.0, 0.0))


def test_attitude_reference_at_stamp_per_mode() -> None:
    q = axis_angle((1.0, 0.0, 1.0), 0.3)
    w, w_ref = (0.5, -0.5, 0.5), (0.0, 1.0, 0.0)
    assert attitude_reference_at_stamp("initial", q, w, None, w_ref)[1] is False
    q_ref, propagate = attitude_reference_at_stamp("integrate_w_ref", q, w, None, w_ref)
    np.testing.assert_array_equal(q_ref, q)
    assert propagate
    q_ref, propagate = attitude_reference_at_stamp("momentum_aligned", q, w, TABLE_II_I0, w_ref)
    np.testing.assert_array_equal(q_ref, momentum_aligned_attitude(q, w, TABLE_II_I0, w_ref))
    assert propagate
    with pytest.raises(ValueError, match="principal_inertia_kg_m2"):
        attitude_reference_at_stamp("momentum_aligned", q, w, None, w_ref)
    with pytest.raises(ValueError, match="attitude_reference"):
        attitude_reference_at_stamp("spin", q, w, None, w_ref)


def test_machine_in_momentum_aligned_mode() -> None:
    """First tick: the aligned reference, which keeps body y along H as it propagates;
    Landing (w_ref = 0, no axis): the measured attitude."""
    config = GaitConfig(
        jumps=(jump(0.0, "auto", 0.1),),
        landing_w_ref_rad_s=(0.0, 0.0, 0.0),
        attitude_reference="momentum_aligned",
    )
    machine = GaitPhaseMachine(config)
    with pytest.raises(ValueError, match="principal_inertia_kg_m2"):
        tick(machine, 0, normal=(STANCE_N, STANCE_N), orientation=TABLE_II_Q0, rate=TABLE_II_W0)
    with pytest.raises(ValueError, match="principal_inertia_kg_m2"):
        tick(machine, 0, orientation=TABLE_II_Q0, rate=TABLE_II_W0, inertia=(0.5, -1.0, 1.0))
    assert machine.phase is None  # the rejected calls changed nothing
    out = tick(
        machine,
        0,
        normal=(STANCE_N, STANCE_N),
        orientation=TABLE_II_Q0,
        rate=TABLE_II_W0,
        inertia=TABLE_II_I0,
    )
    reference = out.reference
    assert reference is not None and reference.propagate and reference.stamp_ns == 0
    np.testing.assert_allclose(
        reference.q_ref_wxyz,
        momentum_aligned_attitude(TABLE_II_Q0, TABLE_II_W0, TABLE_II_I0, (0.0, 1.0, 0.0)),
        atol=1e-15,
    )
    momentum = world_momentum(TABLE_II_Q0, TABLE_II_W0, TABLE_II_I0)
    for t_s in (0.0, 0.37, 2.0, 8.0):
        q_t = reference.attitude_at(round(t_s * 1e9))
        np.testing.assert_allclose(rotate(q_t, E_Y), momentum / np.linalg.norm(momentum), 1e-12)
    q_landing = axis_angle((1.0, 0.0, 0.0), 0.5)
    outputs = [
        tick(machine, k * TICK_NS, orientation=q_landing, rate=(0, 0.3, 0), inertia=TABLE_II_I0)
        for k in range(1, 20)
    ]
    landing = [o for o in outputs if o.reference is not None]
    assert len(landing) == 1 and landing[0].phase == GaitPhase.LANDING
    np.testing.assert_allclose(landing[0].reference.q_ref_wxyz, q_landing, atol=1e-15)


def test_propagate_attitude_matches_closed_form_and_keeps_unit_norm() -> None:
    q = propagate_attitude(IDENTITY, (0.0, 0.0, 2.0), 0.25)  # 0.5 rad about z
    np.testing.assert_allclose(q, axis_angle((0, 0, 1), 0.5), atol=1e-15)
    q = IDENTITY
    for _ in range(1000):
        q = propagate_attitude(q, (0.3, -0.9, 0.9), 0.01)
    assert abs(np.linalg.norm(q) - 1.0) < 1e-12


def test_bad_inputs_raise_and_leave_the_machine_unchanged() -> None:
    machine = GaitPhaseMachine(GaitConfig(jumps=(jump(0.0, "b"),)))
    tick(machine, 0, normal=(0.0, STANCE_N))
    with pytest.raises(ValueError, match="velocity_m_s"):
        tick(machine, 10 * MS, velocity=(math.nan, 0, 0))
    with pytest.raises(ValueError, match="contact_normal_force_n"):
        tick(machine, 10 * MS, normal=(math.inf, 0.0))
    with pytest.raises(ValueError, match="radius_x_m"):
        tick(machine, 10 * MS, radius_x_m=0.0)
    with pytest.raises(ValueError, match="does not follow"):
        tick(machine, 0)
    out = tick(machine, 10 * MS)  # the rejected calls did not consume tick 10 ms
    assert out.thrusting and out.phase == GaitPhase.LAUNCH


def test_same_inputs_give_identical_outputs() -> None:
    config = GaitConfig(jumps=(jump(0.0, "b"), jump(1.0, "auto")), landed_dwell_s=0.2)
    rng = np.random.default_rng(7)

    def normal_at(t_ms: int) -> np.ndarray:
        """Noisy contact forces: on the ground 0-0.2 s and 0.8-1.2 s, then from 2 s."""
        grounded = t_ms < 200 or 800 <= t_ms < 1200 or t_ms >= 2000
        return rng.uniform(3.0, 30.0, 2) if grounded else rng.uniform(0.0, 2.0, 2)

    inputs = [
        (
            k * TICK_NS,
            rng.normal(scale=0.01 if k >= 220 else 1.0, size=3),
            axis_angle(rng.normal(size=3), k * 0.01),
            normal_at(10 * k),
        )
        for k in range(300)
    ]
    runs = []
    for _ in range(2):
        machine = GaitPhaseMachine(config)
        outputs = [tick(machine, t, normal=n, velocity=v, orientation=q) for t, v, q, n in inputs]
        runs.append(
            [
                (
                    o.phase,
                    o.reason,
                    o.on_ground,
                    o.pushing_hemi,
                    o.jumps_done,
                    o.jump_force_n.tolist(),
                    o.jump_torque_nm.tolist(),
                    None if o.reference is None else o.reference.q_ref_wxyz.tolist(),
                )
                for o in outputs
            ]
        )
    assert runs[0] == runs[1]
    # The run is not trivial: both jumps, through every phase but LANDED (never at rest).
    phases = {row[0] for row in runs[0]}
    assert {GaitPhase.LAUNCH, GaitPhase.IN_FLIGHT, GaitPhase.JUMP, GaitPhase.LANDING} <= phases
    assert runs[0][-1][4] == 2


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"stance_force_threshold_n": 0.0}, "stance_force_threshold_n"),
        ({"touchdown_debounce_s": -1.0}, "touchdown_debounce_s"),
        ({"liftoff_debounce_s": -1.0}, "liftoff_debounce_s"),
        ({"landed_dwell_s": -1.0}, "landed_dwell_s"),
        ({"w_ref_rad_s": (0.0, math.nan, 0.0)}, "w_ref_rad_s"),
        ({"attitude_reference": "spin"}, "attitude_reference"),
        ({"jumps": (jump(1.0, "b"), jump(1.1, "a"))}, "jump 1"),
        ({"jumps": (jump(0.0, "c"),)}, "jump 0: hemi"),
    ],
)
def test_invalid_config_names_the_field(kwargs: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        GaitConfig(**kwargs)


def test_the_config_file_gives_the_defaults() -> None:
    """gait_phase_manager.yaml and GaitConfig agree (touchdown_debounce_s included)."""
    data = yaml.safe_load(CONFIG_FILE.read_text(encoding="utf-8"))
    params = data["gait_phase_manager"]["ros__parameters"]
    assert gait_config_from_parameters(params) == GaitConfig()
    config = gait_config_from_parameters({**params, "touchdown_debounce_s": 0.02})
    assert config.touchdown_debounce_ns == 20 * MS


@pytest.mark.parametrize(
    ("arrays", "parameter"),
    [
        (([0.0], [40.0, 0.0], [0.6], ["b"]), "jump_forces_n"),
        (([0.0], [40.0, 0.0, 40.0], [], ["b"]), "jump_durations_s"),
        (([0.0], [40.0, 0.0, 40.0], [0.6], ["x"]), "jump_hemis"),
        (([-1.0], [40.0, 0.0, 40.0], [0.6], ["b"]), "jump_times_s"),
        (([0.0], [40.0, 0.0, 40.0], [0.0], ["b"]), "jump_durations_s"),
        (([0.0, 0.5], [40.0, 0.0, 40.0] * 2, [0.6, 0.6], ["b", "a"]), "jump_times_s"),
        (([0.0], [40.0, math.nan, 40.0], [0.6], ["b"]), "jump_forces_n"),
    ],
)
def test_invalid_plan_arrays_name_the_parameter(arrays: tuple, parameter: str) -> None:
    with pytest.raises(ValueError, match=parameter):
        jump_plan_from_arrays(*arrays)


@pytest.mark.parametrize(
    ("params", "name"),
    [
        ({"liftoff_debounce_s": -0.1}, "liftoff_debounce_s"),
        ({"touchdown_debounce_s": math.nan}, "touchdown_debounce_s"),
        ({"landed_dwell_s": math.inf}, "landed_dwell_s"),
        ({"landing_w_ref_rad_s": [0.0, 0.0]}, "landing_w_ref_rad_s"),
        ({"jump_times_s": [0.0], "jump_forces_n": [1.0, 2.0, 3.0]}, "jump_durations_s"),
    ],
)
def test_config_from_parameters_names_the_bad_one(params: dict, name: str) -> None:
    with pytest.raises(ValueError, match=f"^{name}"):
        gait_config_from_parameters(params)


# --- the timed landing (attitude_reference: landing_timed) ------------------------------------
@pytest.mark.parametrize("seed", range(8))
def test_a_timed_landing_meets_the_ground_with_the_tether_level(seed: int) -> None:
    """The reference, propagated to the predicted touchdown, has the tether level and the
    belly along the conserved momentum, at the spin nearest the one the momentum has."""
    rng = np.random.default_rng(seed)
    q = rng.standard_normal(4)
    q /= np.linalg.norm(q)
    inertia = np.array([0.5, 141.4, 150.0])  # [kg m^2] the belly axis the largest
    w = rng.uniform(-0.2, 0.2, 3) + np.array([0.0, 0.0, 0.45])
    touchdown_s = float(rng.uniform(1.5, 4.5))
    q_ref, w_ref = timed_landing_reference(
        q, w, inertia, touchdown_s, tilt_tolerance_deg=0.0, rate_max_rad_s=math.inf
    )
    momentum = quaternion_to_matrix(q) @ (inertia * w)
    h = momentum / np.linalg.norm(momentum)
    at_touchdown = quaternion_to_matrix(propagate_attitude(q_ref, w_ref, touchdown_s))
    assert abs(at_touchdown[2, 0]) < 1e-9  # the tether (body x) level
    np.testing.assert_allclose(at_touchdown[:, 2], h, atol=1e-9)  # the belly along H
    assert w_ref[0] == 0.0 and w_ref[1] == 0.0 and w_ref[2] > 0.0
    rate_now = np.linalg.norm(momentum) / inertia[2]
    assert abs(w_ref[2] - rate_now) <= math.pi / touchdown_s + 1e-9


def test_a_timed_landing_spins_up_no_faster_than_the_cap() -> None:
    """A slow spin (a second flight's) is timed only by a spin no faster than the cap,
    or not at all; without the cap the nearest timing spins it up beyond it."""
    rng = np.random.default_rng(7)
    inertia = np.array([0.5, 141.4, 150.0])  # [kg m^2]
    fastest_uncapped, timed, untimed = 0.0, 0, 0
    for _ in range(200):
        q = rng.standard_normal(4)
        q /= np.linalg.norm(q)
        spin = np.array([0.0, 0.0, rng.uniform(0.05, 0.45)])  # [rad/s] about the belly
        touchdown_s = float(rng.uniform(2.0, 4.5))
        plan = timed_landing_reference(q, spin, inertia, touchdown_s)
        free = timed_landing_reference(q, spin, inertia, touchdown_s, rate_max_rad_s=math.inf)
        if free is None:  # nothing to time, capped or not
            assert plan is None
            continue
        fastest_uncapped = max(fastest_uncapped, float(free[1][2]))
        if plan is None:
            untimed += 1
            continue
        assert 0.0 < plan[1][2] <= LANDING_RATE_MAX_RAD_S + 1e-12
        timed += 1
    assert fastest_uncapped > 2.0 * LANDING_RATE_MAX_RAD_S
    assert timed > 20 and untimed > 20


def _tether_tilt_at_touchdown(plan, touchdown_s: float) -> float:
    """[rad] the tether's angle from level when the two-spin reference meets the ground."""
    if plan.spin_up_s == 0.0:
        q = propagate_attitude(
            plan.attitude_wxyz, plan.spin_axis_body * plan.spin_up_rad_s, touchdown_s
        )
    else:
        q_switch, w_landing = plan.switch()
        q = propagate_attitude(q_switch, w_landing, touchdown_s - plan.spin_up_s)
    return math.asin(min(1.0, abs(quaternion_to_matrix(q)[2, 0])))


@pytest.mark.parametrize("seed", range(6))
def test_a_spin_up_reaches_a_level_touchdown_a_steady_spin_cannot(seed: int) -> None:
    """lunar_jumping's flight: 0.46 rad/s, a 4.4 s flight, the reel able to slow the spin
    by 13 % (2.8 -> 3.0 m). With a tilted momentum many phases need more than a steady
    spin within 0.40-0.5 rad/s reaches; a spin-up to 1.5 rad/s first levels them, ends
    at least settle_s before the touchdown and meets the ground at the spin it had.
    Where even that does not reach, the plan lands nearer level than the coast."""
    rng = np.random.default_rng(seed)
    inertia = np.array([0.5, 141.4, 150.0])  # [kg m^2]
    touchdown_s, settle_s, spin_up = 4.4, 1.5, 1.5  # [s], [s], [rad/s]
    slowest = (2.8 / 3.0) ** 2
    w = np.array([0.0, 0.0, 0.46])  # [rad/s] about the belly
    rate_now = np.linalg.norm(inertia * w) / inertia[2]
    by_spin_up, nearer = 0, 0
    for _ in range(40):
        tilt = axis_angle(rng.standard_normal(3) * (1.0, 1.0, 0.0), rng.uniform(0.1, 0.35))
        q = quaternion_multiply(tilt, axis_angle((0.0, 0.0, 1.0), rng.uniform(0.0, 2 * math.pi)))
        steady = timed_landing_plan(
            q, w, inertia, touchdown_s, slowest_fraction=slowest, spin_up_rad_s=0.0, settle_s=0.0
        )
        plan = timed_landing_plan(
            q, w, inertia, touchdown_s, slowest_fraction=slowest, spin_up_rad_s=spin_up,
            settle_s=settle_s,
        )  # fmt: skip
        if plan is None:  # nothing to time: the spin it has lands level enough
            assert steady is None
            continue
        tilt_at_touchdown = _tether_tilt_at_touchdown(plan, touchdown_s)
        if steady is not None and _tether_tilt_at_touchdown(steady, touchdown_s) < 1e-9:
            # within the steady spins' reach: the same steady spin
            assert plan.spin_up_s == 0.0 and plan.spin_up_rad_s == steady.spin_up_rad_s
            assert slowest * rate_now - 1e-12 <= plan.spin_up_rad_s <= LANDING_RATE_MAX_RAD_S
            assert tilt_at_touchdown < 1e-9
        elif tilt_at_touchdown < 1e-9:
            by_spin_up += 1
            assert 0.0 < plan.spin_up_s <= touchdown_s - settle_s
            assert plan.spin_up_rad_s == spin_up
            assert plan.landing_rate_rad_s == pytest.approx(min(rate_now, LANDING_RATE_MAX_RAD_S))
        else:  # out of reach: nearer level than the coast
            nearer += 1
            coast = LandingTiming(plan.attitude_wxyz, plan.spin_axis_body, rate_now, 0.0, rate_now)
            assert tilt_at_touchdown < _tether_tilt_at_touchdown(coast, touchdown_s)
    assert by_spin_up >= 15


def test_a_spin_up_plan_refuses_bad_reach() -> None:
    inertia = np.array([0.5, 141.4, 150.0])
    tilted = axis_angle([1.0, 0.0, 0.0], 0.3)
    spin = np.array([0.0, 0.0, 0.45])
    for kwargs, name in (
        ({"slowest_fraction": 0.0, "spin_up_rad_s": 1.0, "settle_s": 1.0}, "slowest_fraction"),
        ({"slowest_fraction": 1.5, "spin_up_rad_s": 1.0, "settle_s": 1.0}, "slowest_fraction"),
        ({"slowest_fraction": 0.8, "spin_up_rad_s": math.nan, "settle_s": 1.0}, "spin_up_rad_s"),
        ({"slowest_fraction": 0.8, "spin_up_rad_s": 1.0, "settle_s": -1.0}, "settle_s"),
    ):
        with pytest.raises(ValueError, match=name):
            timed_landing_plan(tilted, spin, inertia, 3.0, **kwargs)
    # A spin-up that would end within settle_s of the touchdown is no plan.
    short = timed_landing_plan(
        tilted, spin, inertia, 0.5, slowest_fraction=0.99, spin_up_rad_s=1.0, settle_s=0.5
    )
    assert short is None or short.spin_up_s == 0.0


def test_the_machine_hands_over_from_the_spin_up_to_the_landing_spin() -> None:
    """landing_timed with landing_spin_up_rad_s: at lift-off the spin-up reference, at
    its end the landing spin's (continuing the same attitude), which Landing's start
    keeps (it used to replace a last flight's timing with the spin slowed); a touchdown
    first drops the pending one."""
    inertia = np.array([0.5, 141.4, 150.0])
    tilt = axis_angle((1.0, 0.0, 0.0), 0.25)
    q0 = quaternion_multiply(tilt, axis_angle((0.0, 0.0, 1.0), 0.4))  # needs a 1.4 s spin-up
    w = np.array([0.0, 0.0, 0.46])
    config = GaitConfig(
        attitude_reference="landing_timed",
        landing_spin_up_rad_s=1.0,
        jumps=(jump(0.0, duration_s=0.2),),
    )

    def fly(touch_at_s: float | None):
        machine = GaitPhaseMachine(config, gravity_m_s2=MOON_G)
        refs = []
        for k in range(600):
            t = k * TICK_NS
            on_ground = k < 20 or (touch_at_s is not None and t >= touch_at_s * 1e9)
            air_s = max(0.0, t / 1e9 - 0.2)  # [s] ballistic from 0.2 s at 3.6 m/s up
            out = tick(
                machine, t, normal=(STANCE_N, STANCE_N) if on_ground else (0.0, 0.0),
                velocity=(0.0, 0.0, 3.6 - MOON_G * air_s), rate=w, orientation=q0,
                position=(0.0, 0.0, 1.5 + 3.6 * air_s - 0.5 * MOON_G * air_s**2),
                inertia=inertia,
            )  # fmt: skip
            if out.reference is not None:
                refs.append((t, out.reference))
        return refs

    refs = fly(None)
    (t_lift, first), (t_switch, second), (t_landing, held) = refs[1], refs[2], refs[3]
    # the first tick's, the lift-off's, the hand-over, and Landing's start: the timing held
    assert len(refs) == 4
    # each stamped at its own tick (a consumer admits nothing older than its last tick)
    assert (first.stamp_ns, second.stamp_ns, held.stamp_ns) == (t_lift, t_switch, t_landing)
    assert np.linalg.norm(first.w_ref_rad_s) == pytest.approx(1.0)
    assert np.linalg.norm(second.w_ref_rad_s) == pytest.approx(0.46, rel=1e-6)
    # the same attitude path, slower from the spin-up's end (within the tick it ended in)
    gap = quaternion_multiply(
        first.attitude_at(t_switch) * np.array([1.0, -1.0, -1.0, -1.0]), second.q_ref_wxyz
    )
    assert 2.0 * math.asin(min(1.0, np.linalg.norm(gap[1:]))) < (1.0 - 0.46) * TICK_NS / 1e9
    later = t_landing + 10**9
    np.testing.assert_allclose(held.attitude_at(later), second.attitude_at(later), atol=1e-9)
    np.testing.assert_array_equal(held.w_ref_rad_s, second.w_ref_rad_s)
    landed_first = fly((t_lift + (t_switch - t_lift) // 2) / 1e9)
    assert all(ref.stamp_ns < t_switch for _t, ref in landed_first)


def test_nothing_to_time_without_a_tilted_momentum_or_time() -> None:
    inertia = np.array([0.5, 141.4, 150.0])
    spin = np.array([0.0, 0.0, 0.45])  # about the vertical: level at every phase
    assert timed_landing_reference(IDENTITY, spin, inertia, 3.0) is None
    assert timed_landing_reference(IDENTITY, np.zeros(3), inertia, 3.0) is None
    tilted = axis_angle([1.0, 0.0, 0.0], 0.3)
    slightly = axis_angle([1.0, 0.0, 0.0], math.radians(2.9))  # within the 3 deg tolerance
    assert timed_landing_reference(slightly, spin, inertia, 3.0) is None
    assert timed_landing_reference(
        slightly, spin, inertia, 3.0, tilt_tolerance_deg=2.8, rate_max_rad_s=math.inf
    )
    assert timed_landing_reference(tilted, spin, inertia, 0.0) is None
    assert timed_landing_reference(tilted, spin, inertia, math.inf) is None
    assert timed_landing_reference(tilted, spin, inertia, 3.0, rate_max_rad_s=math.inf)


# --- downhill jumps ---------------------------------------------------------------------------
def _plane_normal(slope_deg: float, rise_azimuth_deg: float) -> np.ndarray:
    """Upward unit normal of a plane rising towards ``rise_azimuth_deg`` (from world x)."""
    s, a = math.radians(slope_deg), math.radians(rise_azimuth_deg)
    return np.array([-math.sin(s) * math.cos(a), -math.sin(s) * math.sin(a), math.cos(s)])


def _vertical_speed_at_the_plane(v0: np.ndarray, normal: np.ndarray, g: float) -> float:
    """|v_z| where a ballistic flight from the plane's point at ``v0`` meets it again
    (root of n . (v0 t - g t^2 z / 2), found numerically)."""
    t = np.linspace(1e-3, 20.0, 200_001)
    height = (normal @ v0) * t - 0.5 * g * normal[2] * t * t
    crossing = int(np.argmax(height < 0.0))
    assert crossing > 0
    return abs(v0[2] - g * t[crossing])


@pytest.mark.parametrize("slope_deg", [3.0, 6.0, 10.0])
@pytest.mark.parametrize("heading_deg", [0.0, 30.0, 70.0])
def test_a_downhill_jump_meets_the_plane_no_faster_than_level_ground(
    slope_deg: float, heading_deg: float
) -> None:
    g = MOON_G
    h = math.radians(heading_deg)
    force = np.array([160.0 * math.cos(h), 160.0 * math.sin(h), 350.0])  # [N] whole thrust
    launch = force / TOTAL_MASS_KG - np.array([0.0, 0.0, g])  # [m/s^2] from rest
    v0 = launch / np.linalg.norm(launch) * 3.9  # [m/s] the lift-off velocity, along it
    downhill = _plane_normal(slope_deg, 180.0)  # falls towards +x
    level = _vertical_speed_at_the_plane(v0, np.array([0.0, 0.0, 1.0]), g)
    unscaled = _vertical_speed_at_the_plane(v0, downhill, g)
    scale = downhill_speed_scale(force, downhill, TOTAL_MASS_KG, g)
    scaled = _vertical_speed_at_the_plane(scale * v0, downhill, g)
    assert level == pytest.approx(v0[2], abs=1e-3)
    assert unscaled > level + 0.1 * math.cos(h)  # the plane's drop: faster
    assert scaled == pytest.approx(level, abs=2e-3)
    assert scale < 1.0


@pytest.mark.parametrize(
    ("normal", "force"),
    [
        ((0.0, 0.0, 1.0), (160.0, 0.0, 350.0)),  # level
        (tuple(_plane_normal(6.0, 0.0)), (160.0, 0.0, 350.0)),  # uphill
        (tuple(_plane_normal(6.0, 90.0)), (160.0, 0.0, 350.0)),  # across
        (tuple(_plane_normal(6.0, 180.0)), (160.0, 0.0, 20.0)),  # cannot lift the weight
        (tuple(_plane_normal(0.5, 180.0)), (160.0, 0.0, 350.0)),  # below the level slope
    ],
)
def test_a_jump_that_does_not_head_downhill_is_not_scaled(normal, force) -> None:
    assert downhill_speed_scale(force, normal, TOTAL_MASS_KG, MOON_G, 1.0) == 1.0


def test_a_scaled_jump_keeps_its_direction_and_its_weight() -> None:
    weight = TOTAL_MASS_KG * MOON_G  # [N]
    both = PlannedJump(0, (80.0, 40.0, 180.0), 600 * MS, "both", (70.0, -45.0, 175.0), 3.0)
    scaled = scaled_jump(both, 0.9, weight)
    for before, after in ((both.force_n, scaled.force_n), (both.force_b_n, scaled.force_b_n)):
        lift_before = np.asarray(before) - [0.0, 0.0, weight / 2]
        lift_after = np.asarray(after) - [0.0, 0.0, weight / 2]
        np.testing.assert_allclose(lift_after, 0.81 * lift_before, rtol=1e-12)
    assert scaled.couple_n == both.couple_n and scaled.time_ns == both.time_ns
    single = jump(0.0, "a", force=(60.0, 0.0, 100.0))
    lift = np.asarray(scaled_jump(single, 0.5, weight).force_n) - [0.0, 0.0, weight]
    np.testing.assert_allclose(lift, 0.25 * (np.asarray(single.force_n) - [0.0, 0.0, weight]))
    assert scaled_jump(single, 1.0, weight) is single


def test_the_machine_scales_a_jump_from_a_downhill_stance_only() -> None:
    force = (160.0, 0.0, 350.0)  # [N] heading +x
    planned = jump(0.0, "auto", 0.6, force)
    on_slope = quaternion_multiply(IDENTITY, axis_angle((0.0, 1.0, 0.0), math.radians(6.0)))
    normal = quaternion_to_matrix(on_slope)[:, 2]  # body z: tilted towards +x, falls there
    expected = downhill_speed_scale(force, normal, TOTAL_MASS_KG, MOON_G, 1.0)
    assert expected < 0.95
    for q, scale in ((IDENTITY, 1.0), (on_slope, expected)):
        machine = GaitPhaseMachine(GaitConfig(jumps=(planned,)), MOON_G, TOTAL_MASS_KG)
        out = tick(machine, 0, normal=(STANCE_N, STANCE_N), orientation=q)
        assert out.thrusting and out.jump_speed_scale == pytest.approx(scale)
        weight = np.array([0.0, 0.0, TOTAL_MASS_KG * MOON_G])
        np.testing.assert_allclose(
            out.jump_force_n - weight, scale**2 * (np.asarray(force) - weight), atol=1e-9
        )
    flat = GaitPhaseMachine(GaitConfig(jumps=(planned,), jump_level_slope_deg=90.0), MOON_G)
    out = tick(flat, 0, normal=(STANCE_N, STANCE_N), orientation=on_slope)
    assert out.jump_speed_scale == 1.0
    np.testing.assert_allclose(out.jump_force_n, force)


def test_a_bad_level_slope_or_mass_is_refused_naming_it() -> None:
    with pytest.raises(ValueError, match="jump_level_slope_deg"):
        GaitConfig(jump_level_slope_deg=math.nan)
    with pytest.raises(ValueError, match="mass_kg"):
        GaitPhaseMachine(GaitConfig(), MOON_G, -1.0)
