"""Compliant legs: the stance force law of ``splitter_sim.core.legs`` (closed forms, properties)."""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from splitter_sim.core.legs import (
    LANDING_SPEED_M_S,
    LegImpedance,
    foot_hold_force,
    full_stroke_stop_force,
    leg_normal_force,
    leg_stance_force,
    slipped_anchor,
    stroke_left_after_stop_m,
)
from splitter_sim.core.simulator import SimConfig

# The simulator's defaults (SimConfig): weak spring, strong damper, 190 N cap, mu = 0.8.
LEGS = LegImpedance(
    stiffness_n_m=40.0,
    damping_n_s_m=200.0,
    tangential_damping_n_s_m=20.0,
    friction_coefficient=0.8,
    force_max_n=190.0,
    roll_stiffness_nm_rad=24.0,
    roll_damping_nm_s_rad=4.8,
    hold_stiffness_n_m=400.0,
    hold_damping_n_s_m=120.0,
)
SPEED = st.floats(-20.0, 20.0)  # [m/s] a velocity component
VELOCITY = st.tuples(SPEED, SPEED, SPEED)
COMPRESSION = st.floats(1e-6, 0.4)  # [m] within the 0.4 m stroke
IMPEDANCES = st.builds(
    LegImpedance,
    stiffness_n_m=st.floats(0.0, 1e4),
    damping_n_s_m=st.floats(0.0, 1e3),
    tangential_damping_n_s_m=st.floats(0.0, 1e3),
    friction_coefficient=st.floats(0.0, 2.0),
    force_max_n=st.floats(1.0, 500.0),
)
SETTINGS = settings(max_examples=300, deadline=None)


def test_the_simulator_defaults_are_these_legs() -> None:
    """The ride posture off (its stiffness 0), its other settings given."""
    config = SimConfig()
    assert config.legs == replace(
        LEGS,
        posture_stiffness_n_m=0.0,
        posture_damping_n_s_m=60.0,
        posture_weight_n=9.0 * config.gravity_m_s2,
        ride_compression_m=0.4 - 0.2,
        crouch_compression_m=0.4 - 0.02,
        stop_mass_kg=9.0,
        stop_gravity_m_s2=config.gravity_m_s2,
        stroke_m=0.4,
    )
    assert replace(config, leg_full_stroke_stop=False).legs.stop_mass_kg == 0.0


# --- the whole stroke (module docstring "The whole stroke") ----------------------------------
STOP = replace(LEGS, stop_mass_kg=9.0, stop_gravity_m_s2=1.62, stroke_m=0.4, stop_reserve_m=0.01)


def test_the_whole_stroke_stop_is_the_force_that_stops_at_the_stroke_end() -> None:
    # 2 m/s down with 0.09 m of stroke left: m (g + v^2 / 2 d).
    assert full_stroke_stop_force(0.3, -2.0, STOP) == pytest.approx(9.0 * (1.62 + 4.0 / 0.18))
    assert leg_normal_force(0.3, -2.0, STOP) == STOP.force_max_n  # 214 N, capped
    # Where the damper is the stronger (early in a stop), the law is unchanged.
    assert leg_normal_force(0.05, -1.0, STOP) == leg_normal_force(0.05, -1.0, LEGS)
    # Slow near the stroke's end, the damper alone would let it strike: 0.5 m/s with 1 cm
    # left (besides the reserve) takes 9 (1.62 + 0.25 / 0.02) = 127.1 N, the damper 115.2 N.
    assert leg_normal_force(0.38, -0.5, LEGS) == pytest.approx(40.0 * 0.38 + 100.0)
    assert leg_normal_force(0.38, -0.5, STOP) == pytest.approx(9.0 * (1.62 + 0.25 / 0.02))
    # From rest it grows in over STOP_BLEND_SPEED_M_S (0.1 m/s): continuous at v = 0, so
    # a hemi at rest is held by the law above, not by the nominal hemi's weight.
    assert full_stroke_stop_force(0.3, -0.01, STOP) == pytest.approx(
        0.1 * 9.0 * (1.62 + 0.0001 / 0.18)
    )
    assert full_stroke_stop_force(0.3, -1e-9, STOP) < 1e-6
    # No stroke left: the cap; going up, or off: nothing of its own.
    assert full_stroke_stop_force(0.395, -0.1, STOP) == STOP.force_max_n
    assert full_stroke_stop_force(0.3, 0.5, STOP) == 0.0
    assert full_stroke_stop_force(0.3, -2.0, LEGS) == 0.0
    # A crouch sinks to the stroke's end on purpose: the posture's law alone.
    assert LUNAR.stop_mass_kg == 9.0  # the simulator's default: on
    no_stop = replace(LUNAR, stop_mass_kg=0.0)
    assert leg_normal_force(0.385, -0.6, LUNAR, crouch=True) == leg_normal_force(
        0.385, -0.6, no_stop, crouch=True
    )
    assert leg_normal_force(0.385, -0.6, LUNAR) == LUNAR.force_max_n
    assert leg_normal_force(0.385, -0.6, no_stop) < 120.0


def test_the_stroke_left_after_a_stop_at_the_cap() -> None:
    """s - v^2 / (2 (F / m - g)): the nominal lunar touchdown keeps 6 cm, none at v_max."""
    g = 9.80665 / 6.0  # [m/s^2]
    assert stroke_left_after_stop_m(3.63, 9.0, 190.0, g, 0.4) == pytest.approx(
        0.4 - 3.63**2 / (2.0 * (190.0 / 9.0 - g))
    )
    assert stroke_left_after_stop_m(3.63, 9.0, 190.0, g, 0.4) == pytest.approx(0.0617, abs=1e-4)
    v_max = math.sqrt(2.0 * 0.4 * (190.0 / 9.0 - g))  # [m/s] 3.95
    assert stroke_left_after_stop_m(v_max, 9.0, 190.0, g, 0.4) == pytest.approx(0.0, abs=1e-12)
    assert stroke_left_after_stop_m(4.2, 9.0, 190.0, g, 0.4) < 0.0  # the stroke cannot
    assert stroke_left_after_stop_m(0.0, 9.0, 190.0, g, 0.4) == 0.4
    with pytest.raises(ValueError, match="force_max_n"):
        stroke_left_after_stop_m(3.0, 9.0, 9.0 * g, g, 0.4)  # the cap only holds the weight


@SETTINGS
@given(compression=COMPRESSION, speed=st.floats(0.0, 20.0))
def test_the_whole_stroke_stop_never_weakens_the_law_nor_passes_the_cap(
    compression: float, speed: float
) -> None:
    with_stop = leg_normal_force(compression, -speed, STOP)
    assert leg_normal_force(compression, -speed, LEGS) <= with_stop <= STOP.force_max_n


# --- the ride posture (module docstring "Ride height") ---------------------------------------
POSTURE_N_M = 300.0  # [N/m] the posture measured (README "Ride height")
LUNAR = SimConfig(gravity_m_s2=1.62, leg_posture_stiffness_n_m=POSTURE_N_M).legs  # W 14.58 N


def test_a_standing_hemi_is_held_at_the_ride_height_and_a_crouching_one_lowered() -> None:
    w, k_p = LUNAR.posture_weight_n, LUNAR.posture_stiffness_n_m
    assert w == pytest.approx(14.58)
    # Standing: the weight at the ride compression, a spring about it, a damper.
    assert leg_normal_force(0.2, 0.0, LUNAR) == pytest.approx(w)
    assert leg_normal_force(0.25, 0.0, LUNAR) == pytest.approx(w + k_p * 0.05)
    assert leg_normal_force(0.18, 0.0, LUNAR) == pytest.approx(w - k_p * 0.02)
    assert leg_normal_force(0.2, 0.1, LUNAR) == pytest.approx(w - 6.0)
    assert leg_normal_force(0.2, -0.3, LUNAR) == pytest.approx(w + 18.0)
    # Crouching: the weight at the crouch compression; above it the legs carry half the
    # weight (the hemi sinks at g / 2), never nothing.
    assert leg_normal_force(0.38, 0.0, LUNAR, crouch=True) == pytest.approx(w)
    assert leg_normal_force(0.2, 0.0, LUNAR, crouch=True) == pytest.approx(w / 2.0)
    assert leg_normal_force(0.2, 0.3, LUNAR, crouch=True) == pytest.approx(w / 2.0)


def test_a_touchdown_keeps_the_spring_damper_stop() -> None:
    """Coming down faster than a crouch, the legs stop the hemi at least as hard as without
    the posture, and exactly so from the landing speed's upper end; continuously between."""
    bare = replace(LUNAR, posture_stiffness_n_m=0.0)
    for compression in (0.01, 0.1, 0.3):
        for down in (LANDING_SPEED_M_S[1], 1.5, 3.6):
            with_posture = leg_normal_force(compression, -down, LUNAR)
            without = leg_normal_force(compression, -down, bare)
            assert with_posture == pytest.approx(max(without, with_posture))
            assert with_posture >= without - 1e-12
    assert leg_normal_force(0.01, -3.6, LUNAR) == LUNAR.force_max_n
    speeds = [LANDING_SPEED_M_S[0] + i * 1e-4 for i in range(-5, 6006)]
    forces = [leg_normal_force(0.3, -v, LUNAR) for v in speeds]
    assert max(abs(b - a) for a, b in itertools.pairwise(forces)) < 0.1  # [N]


def test_without_a_posture_the_law_is_the_spring_damper() -> None:
    bare = replace(LUNAR, posture_stiffness_n_m=0.0)
    assert leg_normal_force(0.3, -0.5, bare) == pytest.approx(40.0 * 0.3 + 200.0 * 0.5)
    assert leg_normal_force(0.3, 0.0, bare, crouch=True) == pytest.approx(12.0)


@pytest.mark.parametrize(
    ("field", "value"),
    [("posture_weight_n", math.nan), ("crouch_compression_m", -0.1), ("ride_compression_m", -1.0)],
)
def test_an_invalid_posture_names_the_field(field: str, value: float) -> None:
    with pytest.raises(ValueError, match=field):
        replace(LUNAR, **{field: value})


@pytest.mark.parametrize("compression_m", [0.0, -1e-12, -0.05, -3.0])
@pytest.mark.parametrize("velocity", [(0.0, 0.0, 0.0), (1.0, -2.0, -3.0), (0.0, 0.0, 5.0)])
def test_no_force_without_compression(compression_m: float, velocity) -> None:
    assert leg_stance_force(compression_m, velocity, LEGS) == (0.0, 0.0, 0.0)


def test_closed_forms_below_the_caps() -> None:
    # Standing still: the spring alone, k x.
    assert leg_stance_force(0.3, (0.0, 0.0, 0.0), LEGS) == (0.0, 0.0, pytest.approx(12.0))
    # Going down at 0.5 m/s: k x + c v_down = 4 + 100 N.
    assert leg_stance_force(0.1, (0.0, 0.0, -0.5), LEGS) == (0.0, 0.0, pytest.approx(104.0))
    # Sliding at 0.5 m/s along -y: the hip damping asks for 10 N along +y, the friction
    # cone of the 12 N normal force allows 0.8 x 12 = 9.6 N.
    fx, fy, fz = leg_stance_force(0.3, (0.0, -0.5, 0.0), LEGS)
    assert (fx, fz) == (0.0, pytest.approx(12.0))
    assert fy == pytest.approx(0.8 * 12.0)
    # Sliding slowly at 0.1 m/s along +x: 2 N of hip damping, below the cone.
    fx, fy, fz = leg_stance_force(0.3, (0.1, 0.0, 0.0), LEGS)
    assert (fx, fy, fz) == (pytest.approx(-2.0), 0.0, pytest.approx(12.0))


def test_a_hard_touchdown_saturates_the_normal_force_and_leaves_no_tangential() -> None:
    """3 m/s down: c v = 600 N, capped at 190 N, all of it normal (it has priority)."""
    force = leg_stance_force(0.05, (2.0, 1.0, -3.0), LEGS)
    assert force == (0.0, 0.0, 190.0)  # sqrt(190^2 - 190^2) = 0 left for the tangential


def test_the_normal_force_has_priority_near_the_cap() -> None:
    # Normal 180 N (k x + c v_down = 4 + 176): at most sqrt(190^2 - 180^2) = 60.8 N of the
    # 0.8 x 180 = 144 N the cone allows are left, and the 200 N of hip damping get that.
    force = leg_stance_force(0.1, (-10.0, 0.0, -0.88), LEGS)
    assert force[2] == pytest.approx(180.0)
    assert force[0] == pytest.approx(math.sqrt(190.0**2 - 180.0**2))
    assert math.hypot(*force) == pytest.approx(190.0)
    # The same normal force as without sliding.
    assert leg_stance_force(0.1, (0.0, 0.0, -0.88), LEGS)[2] == force[2]


def test_moving_up_fast_the_legs_let_go() -> None:
    # k x - c v_up < 0: no pull, and no tangential force either (nothing in the cone).
    assert leg_stance_force(0.2, (3.0, 0.0, 1.0), LEGS) == (0.0, 0.0, 0.0)
    # Slower: the spring still wins, 8 - 4 = 4 N.
    assert leg_stance_force(0.2, (0.0, 0.0, 0.02), LEGS)[2] == pytest.approx(4.0)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("stiffness_n_m", -1.0),
        ("damping_n_s_m", math.nan),
        ("tangential_damping_n_s_m", -0.1),
        ("friction_coefficient", math.inf),
        ("force_max_n", 0.0),
        ("force_max_n", math.inf),
    ],
)
def test_invalid_impedance_names_the_field(field: str, value: float) -> None:
    kwargs = {
        "stiffness_n_m": 40.0,
        "damping_n_s_m": 200.0,
        "tangential_damping_n_s_m": 20.0,
        "friction_coefficient": 0.8,
        "force_max_n": 190.0,
        field: value,
    }
    with pytest.raises(ValueError, match=field):
        LegImpedance(**kwargs)


@SETTINGS
@given(legs=IMPEDANCES, compression_m=st.floats(-1.0, 0.4), velocity=VELOCITY)
def test_the_legs_never_pull_and_never_exceed_the_cap(
    legs: LegImpedance, compression_m: float, velocity: tuple[float, float, float]
) -> None:
    force = leg_stance_force(compression_m, velocity, legs)
    assert all(math.isfinite(f) for f in force)
    assert force[2] >= 0.0
    assert math.hypot(*force) <= legs.force_max_n * (1.0 + 1e-12)
    if compression_m <= 0.0 or force[2] == 0.0:
        assert force == (0.0, 0.0, 0.0)


@SETTINGS
@given(legs=IMPEDANCES, compression_m=COMPRESSION, velocity=VELOCITY)
def test_the_normal_force_is_the_capped_impedance_and_the_tangential_opposes_the_sliding(
    legs: LegImpedance, compression_m: float, velocity: tuple[float, float, float]
) -> None:
    fx, fy, fz = leg_stance_force(compression_m, velocity, legs)
    # The normal force: the capped impedance whatever the sliding.
    impedance = legs.stiffness_n_m * compression_m - legs.damping_n_s_m * velocity[2]
    assert fz == pytest.approx(min(max(impedance, 0.0), legs.force_max_n), rel=1e-12, abs=1e-12)
    # Priority: sliding never takes anything from the normal force.
    assert leg_stance_force(compression_m, (0.0, 0.0, velocity[2]), legs)[2] == fz
    # The tangential force: in the friction cone, within the damping, against the sliding.
    vx, vy, _ = velocity
    f_t = math.hypot(fx, fy)
    assert f_t <= legs.friction_coefficient * fz * (1.0 + 1e-12) + 1e-12
    assert f_t <= legs.tangential_damping_n_s_m * math.hypot(vx, vy) * (1.0 + 1e-12)
    if f_t > 0.0:
        # Anti-parallel to the horizontal velocity: f_t . v_t = -|f_t| |v_t|, no cross part.
        speed = math.hypot(vx, vy)
        assert fx * vx + fy * vy == pytest.approx(-f_t * speed, rel=1e-9)
        assert abs(fx * vy - fy * vx) <= 1e-9 * f_t * speed + 1e-300


@SETTINGS
@given(
    compression=COMPRESSION,
    velocity=VELOCITY,
    legs=IMPEDANCES,
    hold=st.tuples(st.floats(-500.0, 500.0), st.floats(-500.0, 500.0)),
)
def test_planted_feet_stay_within_the_cap_and_the_friction_cone(
    compression: float, velocity, legs: LegImpedance, hold
) -> None:
    fx, fy, fz = leg_stance_force(compression, velocity, legs, (0.0, 0.0, 1.0), hold)
    assert fz >= 0.0
    assert math.hypot(fx, fy, fz) <= legs.force_max_n * (1 + 1e-9) + 1e-9
    assert math.hypot(fx, fy) <= legs.friction_coefficient * fz * (1 + 1e-9) + 1e-9


def test_planted_feet_pull_back_towards_where_they_stuck() -> None:
    hold = foot_hold_force((0.01, -0.02), LEGS)  # the hemi 1 cm ahead, 2 cm right
    assert hold == pytest.approx((-4.0, 8.0))
    fx, fy, fz = leg_stance_force(0.3, (0.0, 0.0, 0.0), LEGS, (0.0, 0.0, 1.0), hold)
    assert (fx, fy) == pytest.approx(hold)
    assert fz == pytest.approx(LEGS.stiffness_n_m * 0.3)


def test_planted_feet_slip_at_the_cone_by_dragging_behind_the_hemi() -> None:
    assert slipped_anchor((0.01, 0.0), (0.0, 0.0), 10.0, LEGS) == (0.0, 0.0)  # 4 N: held
    anchor = slipped_anchor((0.1, 0.0), (0.0, 0.0), 10.0, LEGS)  # 40 N asked, 10 N held
    assert anchor == pytest.approx((0.1 - 10.0 / 400.0, 0.0))
    assert math.hypot(*foot_hold_force((0.1 - anchor[0], 0.0), LEGS)) == pytest.approx(10.0)
