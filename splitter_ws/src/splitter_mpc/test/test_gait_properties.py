"""Gait phase machine: the state machine's invariants on any input (property tests).

hypothesis drives :class:`GaitPhaseMachine` with contact normal forces per hemi
(held for a while, or chattering around the stance threshold tick by tick),
velocities, body rates, attitudes, tick spacings and jump plans of its choosing,
and :func:`check_run` checks every tick against the module docstring:

* (a) every phase change is one of ``ALLOWED_TRANSITIONS``, reported once with a
  reason; the first phase follows from the contact and the plan;
* (b) the debounced ground contact (``on_ground``) flips exactly when the stance
  has lasted ``touchdown_debounce`` without a break, or has been absent for more
  than ``liftoff_debounce`` (never sooner, never later); a phase changes only on
  such an event (touchdown in flight, lift-off from a ground phase, each of which
  always changes it) or by rule: landing on descent after the last jump, LANDED
  after the dwell at rest, Landing for a last jump that never left the ground;
* (c) LANDED is never left;
* (d) each planned jump thrusts at most once, not before its time, from a ground
  phase, through a hemi in stance, with the planned force, for at most its
  duration, ending at the duration or at lift-off; ``jumps_done`` counts the
  finished thrusts and never exceeds the plan;
* (e) nothing in the outputs is NaN or infinite.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from splitter_mpc.core.gait import (
    ALLOWED_TRANSITIONS,
    ATTITUDE_REFERENCE_MODES,
    JUMP_HEMIS,
    GaitConfig,
    GaitOutput,
    GaitPhase,
    GaitPhaseMachine,
    PlannedJump,
    jump_wrench,
)
from splitter_msgs_py import names

MS = 1_000_000  # [ns]
THRESHOLD_N = 2.0  # [N] stance_force_threshold_n of every drawn config
INERTIA_KG_M2 = (0.48, 141.36, 141.36)  # [kg m^2] paper Table I shape
GROUND_PHASES = (GaitPhase.LAUNCH, GaitPhase.JUMP)
LANDING_PHASES = (GaitPhase.LANDING, GaitPhase.LANDED)
SETTINGS = settings(max_examples=150, deadline=None)

# Contact normal forces [N]: none, below, at (not stance) and just above the threshold,
# a hemi's lunar weight, the legs' cap.
FORCE = st.one_of(
    st.sampled_from((0.0, 1.0, THRESHOLD_N, THRESHOLD_N + 1e-9, 14.6, 190.0)),
    st.floats(0.0, 200.0),
)
# Speeds [m/s] and rates [rad/s] often at rest (exactly, or just under / over 0.05).
COMPONENT = st.one_of(
    st.just(0.0),
    st.sampled_from((-0.049, -0.03, 0.02, 0.049, 0.051)),
    st.floats(-5.0, 5.0),
)
VECTOR3 = st.one_of(
    st.just((0.0, 0.0, 0.0)),
    st.tuples(st.just(0.0), st.just(0.0), COMPONENT),
    st.tuples(*[COMPONENT] * 3),
)
TICK_NS = st.one_of(st.sampled_from((5 * MS, 10 * MS, 10 * MS, 20 * MS)), st.integers(1, 40 * MS))
QUATERNION = st.tuples(*[st.floats(-1.0, 1.0)] * 4).map(
    lambda q: q if math.fsum(c * c for c in q) > 0.01 else (1.0, 0.0, 0.0, 0.0)
)


@dataclass(frozen=True)
class Tick:
    """One update's inputs."""

    t_ns: int
    normal_n: tuple[float, float]
    velocity_m_s: tuple[float, float, float]
    rate_rad_s: tuple[float, float, float]
    orientation_wxyz: tuple[float, float, float, float]
    height_m: float
    radius_x_m: float


@st.composite
def jump_plans(draw: st.DrawFn) -> tuple[PlannedJump, ...]:
    """0-3 jumps, each after the end of the one before (the plan's rule)."""
    jumps = []
    t_ns = draw(st.integers(0, 300)) * MS
    for _ in range(draw(st.integers(0, 3))):
        duration_ns = draw(st.integers(1, 400)) * MS
        force = draw(st.tuples(*[st.floats(-400.0, 400.0)] * 3))
        hemi = draw(st.sampled_from(JUMP_HEMIS))
        force_b = draw(st.tuples(*[st.floats(-400.0, 400.0)] * 3)) if hemi == "both" else (0.0,) * 3
        jumps.append(PlannedJump(t_ns, force, duration_ns, hemi, force_b))
        t_ns += duration_ns + draw(st.integers(0, 800)) * MS
    return tuple(jumps)


@st.composite
def configs(draw: st.DrawFn) -> GaitConfig:
    return GaitConfig(
        jumps=draw(jump_plans()),
        stance_force_threshold_n=THRESHOLD_N,
        touchdown_debounce_s=draw(st.sampled_from((0, 10, 50, 80))) / 1000,
        liftoff_debounce_s=draw(st.sampled_from((0, 20, 150))) / 1000,
        landed_dwell_s=draw(st.sampled_from((0, 30, 200))) / 1000,
        jump_settle_speed_m_s=draw(st.sampled_from((0.1, 10.0))),
        jump_settle_angular_speed_rad_s=draw(st.sampled_from((0.05, 10.0))),
        attitude_reference=draw(st.sampled_from(ATTITUDE_REFERENCE_MODES)),
    )


@st.composite
def segments(draw: st.DrawFn) -> list[Tick]:
    """Inputs as runs of 1-40 ticks, each of one kind.

    ``hold``: any forces, velocity and rate, held; ``chatter``: forces drawn anew
    every tick; ``flight``: no stance, v_z falling from a take-off speed through
    the apex; ``rest``: on both hemis, still (or nearly).
    """
    ticks: list[Tick] = []
    t_ns = draw(st.integers(0, 50 * MS))
    for _ in range(draw(st.integers(1, 14))):
        kind = draw(st.sampled_from(("hold", "chatter", "flight", "rest")))
        length = draw(st.integers(1, 40))
        normal = (draw(FORCE), draw(FORCE))
        velocity, rate = draw(VECTOR3), draw(VECTOR3)
        fall_m_s2 = 0.0  # [m/s^2]
        if kind == "flight":
            normal = (0.0, draw(st.sampled_from((0.0, 1.0, THRESHOLD_N))))
            velocity = (velocity[0], velocity[1], draw(st.floats(0.0, 1.5)))
            fall_m_s2 = draw(st.sampled_from((1.62, 9.81, 30.0)))
        elif kind == "rest":
            normal = (draw(st.floats(2.5, 50.0)), draw(st.floats(2.5, 50.0)))
            velocity = draw(st.sampled_from(((0.0, 0.0, 0.0), (0.01, 0.0, -0.02))))
            rate = draw(st.sampled_from(((0.0, 0.0, 0.0), (0.0, 0.049, 0.0))))
        orientation = draw(QUATERNION)
        height, radius = draw(st.floats(0.0, 3.0)), draw(st.floats(0.2, 3.0))
        dt_ns = draw(TICK_NS)
        start_ns = t_ns
        for _ in range(length):
            if kind == "chatter":
                normal = (draw(FORCE), draw(FORCE))
            vz = velocity[2] - fall_m_s2 * (t_ns - start_ns) / 1e9  # [m/s]
            v = (velocity[0], velocity[1], vz)
            ticks.append(Tick(t_ns, normal, v, rate, orientation, height, radius))
            t_ns += dt_ns
    return ticks


@st.composite
def chattering(draw: st.DrawFn) -> list[Tick]:
    """Contact forces that flicker around the threshold: runs of 1-12 ticks, 1-20 ms apart."""
    ticks: list[Tick] = []
    t_ns = 0
    velocity = draw(VECTOR3)
    for _ in range(draw(st.integers(1, 40))):
        normal = draw(
            st.sampled_from(
                ((0.0, 0.0), (20.0, 0.0), (0.0, 20.0), (20.0, 20.0), (THRESHOLD_N, 3.0))
            )
        )
        for _ in range(draw(st.integers(1, 12))):
            ticks.append(
                Tick(t_ns, normal, velocity, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0), 0.4, 2.8)
            )
            t_ns += draw(st.integers(1, 20)) * MS
    return ticks


def run(config: GaitConfig, ticks: list[Tick]) -> list[GaitOutput]:
    machine = GaitPhaseMachine(config)
    return [
        machine.update(
            tick.t_ns,
            (0.0, 0.0, tick.height_m),
            tick.velocity_m_s,
            tick.orientation_wxyz,
            tick.rate_rad_s,
            tick.radius_x_m,
            tick.normal_n,
            INERTIA_KG_M2,
        )
        for tick in ticks
    ]


def expected_wrench(jump: PlannedJump, hemi: str, tick: Tick) -> tuple[np.ndarray, np.ndarray]:
    """The planned force through ``hemi``; ``auto``: half through each hemi; ``both``: each
    hemi its own force."""
    q = np.asarray(tick.orientation_wxyz) / np.linalg.norm(tick.orientation_wxyz)
    if hemi == "both":
        fa, ta = jump_wrench(jump.force_n, q, tick.radius_x_m, "a")
        fb, tb = jump_wrench(jump.force_b_n, q, tick.radius_x_m, "b")
        return fa + fb, ta + tb
    if hemi != "auto":
        return jump_wrench(jump.force_n, q, tick.radius_x_m, hemi)
    half = np.asarray(jump.force_n) / 2.0
    parts = [jump_wrench(half, q, tick.radius_x_m, h) for h in names.HEMIS]
    return parts[0][0] + parts[1][0], parts[0][1] + parts[1][1]


def check_outputs_finite(out: GaitOutput) -> None:
    """(e) No NaN or infinity anywhere in an output."""
    arrays = [out.jump_force_n, out.jump_torque_nm, np.asarray(out.hemi_height_m)]
    if out.reference is not None:
        arrays += [
            out.reference.q_ref_wxyz,
            out.reference.w_ref_rad_s,
            out.reference.attitude_at(out.t_ns + 10**9),
        ]
    for array in arrays:
        assert np.all(np.isfinite(array)), out


def check_run(config: GaitConfig, ticks: list[Tick], outputs: list[GaitOutput]) -> None:
    """Every invariant of the module docstring, tick by tick."""
    plan = config.jumps
    td, lo = config.touchdown_debounce_ns, config.liftoff_debounce_ns
    streak_start: int | None = None  # [ns] first tick of the current run of stance
    last_stance: int | None = None  # [ns] last tick with stance
    at_rest_since: int | None = None  # [ns] start of the rest streak counted in LANDING
    phase_since = 0  # [ns]
    thrusts: list[tuple[int, str]] = []  # (start [ns], pushing hemi) of each thrust
    last_thrust_end: int | None = None  # [ns]
    prev: GaitOutput | None = None
    for tick, out in zip(ticks, outputs, strict=True):
        t = tick.t_ns
        stance = (tick.normal_n[0] > THRESHOLD_N, tick.normal_n[1] > THRESHOLD_N)
        assert out.t_ns == t and out.stance == stance
        check_outputs_finite(out)
        if any(stance):
            last_stance = t
            streak_start = t if streak_start is None else streak_start
        else:
            streak_start = None
        if prev is None:  # the first tick: the stance as measured
            assert out.on_ground == any(stance) and out.phase_changed and out.reason
            first = GaitPhase.LAUNCH if plan else GaitPhase.LANDING
            assert out.phase == (first if out.on_ground else GaitPhase.IN_FLIGHT)
            assert out.reference is not None and out.reference.stamp_ns == t
        else:
            # (b) The debounce: touchdown once the stance has lasted td without a break,
            # lift-off once it has been absent for more than lo; never sooner or later.
            touchdown_due = streak_start is not None and t - streak_start >= td
            liftoff_due = last_stance is None or t - last_stance > lo
            touchdown = out.on_ground and not prev.on_ground
            liftoff = prev.on_ground and not out.on_ground
            assert out.on_ground == (touchdown_due if not prev.on_ground else not liftoff_due)
            # (a) Changes are reported, allowed and caused.
            changed = out.phase != prev.phase
            assert out.phase_changed == changed and bool(out.reason) == changed
            # (c) LANDED is final.
            assert prev.phase != GaitPhase.LANDED or out.phase == GaitPhase.LANDED
            if changed:
                assert (prev.phase, out.phase) in ALLOWED_TRANSITIONS
            # A touchdown in flight and a lift-off from a ground phase always change it.
            if touchdown and prev.phase == GaitPhase.IN_FLIGHT:
                assert changed
            if liftoff and prev.phase in GROUND_PHASES:
                assert changed
            all_done = out.jumps_done == len(plan) and not out.thrusting
            descending = bool(plan) and all_done and tick.velocity_m_s[2] <= 0.0
            if changed and prev.phase == GaitPhase.IN_FLIGHT:
                if touchdown:
                    assert out.phase == (GaitPhase.LANDING if all_done else GaitPhase.JUMP)
                else:  # by rule: landing on descent after the last jump
                    assert out.phase == GaitPhase.LANDING and descending
            if changed and prev.phase in GROUND_PHASES:
                if liftoff:
                    landing = descending
                    assert out.phase == (GaitPhase.LANDING if landing else GaitPhase.IN_FLIGHT)
                else:  # by rule: the last jump never left the ground (still in stance
                    # the lift-off debounce after its thrust ended)
                    assert out.phase == GaitPhase.LANDING and all_done and out.on_ground
                    assert last_thrust_end is not None and t - last_thrust_end > lo
            # LANDED after landed_dwell at rest on both hemis, counted in LANDING.
            if prev.phase == GaitPhase.LANDING:
                at_rest = (
                    all(stance)
                    and out.on_ground
                    and math.hypot(*tick.velocity_m_s) < config.landed_speed_m_s
                    and math.hypot(*tick.rate_rad_s) < config.landed_angular_speed_rad_s
                )
                if not at_rest:
                    at_rest_since = None
                elif at_rest_since is None:
                    at_rest_since = t
                dwelt = at_rest_since is not None and t - at_rest_since >= config.landed_dwell_ns
                assert (out.phase == GaitPhase.LANDED) == dwelt
            # The references: on the first tick and when Landing starts, never again;
            # landing_timed also at every lift-off (the flight's timed landing).
            landing_starts = out.phase in LANDING_PHASES and prev.phase not in LANDING_PHASES
            if config.attitude_reference == "landing_timed":
                liftoff = prev.on_ground and not out.on_ground
                assert not landing_starts or out.reference is not None
                assert out.reference is None or landing_starts or liftoff
            else:
                assert (out.reference is not None) == landing_starts
            # (d) Thrusts: the running one ends at its duration or at lift-off.
            if prev.thrusting:
                start, hemi = thrusts[-1]
                ends = t >= start + plan[len(thrusts) - 1].duration_ns or liftoff
                assert out.jumps_done == prev.jumps_done + ends
                if ends:
                    last_thrust_end = t
                else:
                    assert out.thrusting and out.pushing_hemi == hemi
            else:
                assert out.jumps_done == prev.jumps_done
        if out.phase_changed:
            phase_since = t
        assert out.time_in_phase_ns == t - phase_since
        assert out.phase not in GROUND_PHASES or out.on_ground
        # (d) A thrust starts: the next planned jump, due, from a ground phase, through
        # the planned hemi in stance (auto: the hemis in stance), once.
        starts = out.thrusting and (prev is None or not prev.thrusting or last_thrust_end == t)
        if starts:
            assert len(thrusts) < len(plan)
            jump = plan[len(thrusts)]
            assert t >= jump.time_ns and out.phase in GROUND_PHASES
            if jump.hemi == "auto":
                expected_hemi = {(1, 0): "a", (0, 1): "b", (1, 1): "auto"}[stance]
            elif jump.hemi == "both":
                expected_hemi = "both"
                assert all(stance)
            else:
                expected_hemi = jump.hemi
                assert stance[names.HEMIS.index(jump.hemi)]
            assert out.pushing_hemi == expected_hemi
            if prev is not None and prev.phase == GaitPhase.JUMP:  # after a touchdown: settled
                assert settled(config, tick)
            thrusts.append((t, expected_hemi))
        elif (
            prev is not None
            and prev.phase in GROUND_PHASES
            and out.phase in GROUND_PHASES
            and not out.thrusting
            and len(thrusts) < len(plan)
            and t >= plan[len(thrusts)].time_ns
        ):  # a due jump not started: its hemi is not in stance, or the robot has not
            # settled after a touchdown; and it says it waits
            hemi = plan[len(thrusts)].hemi
            if hemi == "both":
                in_stance = all(stance)
            else:
                in_stance = any(stance) if hemi == "auto" else stance[names.HEMIS.index(hemi)]
            assert not in_stance or (prev.phase == GaitPhase.JUMP and not settled(config, tick))
            assert out.jump_waiting
        if out.jump_waiting:  # a due jump
            assert not out.thrusting and len(thrusts) < len(plan)
            assert t >= plan[len(thrusts)].time_ns
        if out.thrusting:
            force, torque = expected_wrench(plan[len(thrusts) - 1], out.pushing_hemi, tick)
            np.testing.assert_array_equal(out.jump_force_n, force)
            np.testing.assert_allclose(out.jump_torque_nm, torque, rtol=1e-12, atol=1e-9)
        else:
            assert out.pushing_hemi is None
            assert not out.jump_force_n.any() and not out.jump_torque_nm.any()
        assert 0 <= out.jumps_done <= len(thrusts) <= len(plan) == out.jumps_planned
        prev = out


def settled(config: GaitConfig, tick: Tick) -> bool:
    """The robot is settled enough for a jump after a touchdown (GaitConfig's thresholds)."""
    return (
        abs(tick.velocity_m_s[2]) < config.jump_settle_speed_m_s
        and float(np.linalg.norm(tick.rate_rad_s)) < config.jump_settle_angular_speed_rad_s
    )


@SETTINGS
@given(config=configs(), ticks=segments())
def test_the_machine_keeps_its_invariants(config: GaitConfig, ticks: list[Tick]) -> None:
    check_run(config, ticks, run(config, ticks))


@SETTINGS
@given(config=configs(), ticks=chattering())
def test_chattering_contact_changes_nothing_before_the_debounce(
    config: GaitConfig, ticks: list[Tick]
) -> None:
    check_run(config, ticks, run(config, ticks))
