"""Legs that act where they point: the workspace cone and landings on the body.

A hemi's legs reach along its belly (body ``-z``) and push only while the belly
faces the ground within ``SimConfig.leg_cone_half_angle_deg``; outside it the
hemi lands on its lumped masses, the stiff ground. Each drop is the lunar drop
of ``test_simulator_physics`` (lowest mass 0.45 m up), at 1 m/s down, tilted
about the tether axis, so both hemis meet the ground together. Beyond the friction
angle (atan 0.8 = 39 deg) tilted legs take the touchdown but their feet slip, so a
hemi near the cone's edge later sinks onto its masses: the tests judge the
touchdown, the first 0.2 s of contact.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from splitter_model.model import RobotModel
from splitter_sim.core.legs import (
    LegImpedance,
    leg_compression_m,
    leg_stance_force,
    roll_load_share,
)
from splitter_sim.core.simulator import InitialState, SimConfig, Simulator

MODEL = RobotModel()
DT = 0.005  # [s]
CONE_DEG = SimConfig().leg_cone_half_angle_deg  # [deg]
LEGS = replace(SimConfig().legs, posture_stiffness_n_m=0.0)  # the law (test_legs: posture)


def _drop(roll_deg: float, speed_m_s: float = 1.0, seconds: float = 0.8) -> list:
    """States of a lunar drop rolled by ``roll_deg`` about the tether axis (body x)."""
    config = SimConfig(gravity_m_s2=1.62, compliant_legs=True)
    q_xyzw = Rotation.from_euler("x", roll_deg, degrees=True).as_quat()
    wxyz = (q_xyzw[3], q_xyzw[0], q_xyzw[1], q_xyzw[2])
    probe = Simulator(MODEL, config, InitialState(position_m=(0, 0, 10.0), orientation_wxyz=wxyz))
    lowest = float(probe.state().mass_positions_world_m[:, 2].min()) - 10.0  # [m] from the COM
    sim = Simulator(
        MODEL,
        config,
        InitialState(
            position_m=(0.0, 0.0, 0.45 - lowest),
            velocity_m_s=(0.0, 0.0, -speed_m_s),
            orientation_wxyz=wxyz,
        ),
    )
    states = []
    for _ in range(int(seconds / DT)):
        sim.step()
        states.append(sim.state())
    return states


def _landed_on(states: list, window_s: float = 0.2) -> str:
    """What took the touchdown: the first contact and the ``window_s`` after it.

    "legs": the legs touched first and the impact stayed within their force cap with
    every lumped mass above the ground; "body": the lumped masses touched first, with
    no leg force, and the impact was harder than the legs could ever push.
    """
    force = np.array([float(np.linalg.norm(s.contact_force_n, axis=1).max()) for s in states])
    first = int(np.argmax(force > 0.0))
    assert force[first] > 0.0, "no touchdown"
    window = states[first : first + round(window_s / DT)]
    legs = max(float(np.linalg.norm(s.leg_force_n, axis=1).max()) for s in window)
    lowest = min(float(s.mass_positions_world_m[:, 2].min()) for s in window)
    peak = float(force[first : first + len(window)].max())
    if legs > 0.0 and lowest > 0.0 and peak <= LEGS.force_max_n + 2.0:
        return "legs"
    first_legs = float(np.abs(states[first].leg_force_n).max())
    first_lowest = float(states[first].mass_positions_world_m[:, 2].min())
    if first_legs == 0.0 and first_lowest < 0.0 and peak > 1000.0:
        return "body"  # (the blow may roll the hemi back into the cone: legs later)
    return f"mixed (legs {legs:.0f} N, lowest mass {lowest:.3f} m, peak {peak:.0f} N)"


def test_a_hemi_dropped_upside_down_lands_on_its_body() -> None:
    assert _landed_on(_drop(180.0)) == "body"


def test_a_level_drop_lands_on_the_legs() -> None:
    assert _landed_on(_drop(0.0)) == "legs"


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_the_cone_edge_separates_legs_from_body(sign: float) -> None:
    """A few degrees inside the cone: legs; a few degrees outside: body."""
    assert _landed_on(_drop(sign * (CONE_DEG - 3.0))) == "legs"
    assert _landed_on(_drop(sign * (CONE_DEG + 3.0))) == "body"


def test_tilted_legs_push_along_the_belly() -> None:
    """30 deg tilt, standing still: k x along the belly normal, within the friction cone."""
    tilt = math.radians(30.0)
    belly = (0.0, -math.sin(tilt), math.cos(tilt))
    fx, fy, fz = leg_stance_force(0.3, (0.0, 0.0, 0.0), LEGS, belly)
    # 12 N along the belly: 0.5 x 12 = 6 N along the ground, within mu 0.8 x 10.4 N.
    assert (fx, fy, fz) == (0.0, pytest.approx(-6.0), pytest.approx(12.0 * math.cos(tilt)))
    # The ground is reached farther along a tilted leg: 0.2 m below is 0.231 m along it.
    assert leg_compression_m(0.4, 0.2, math.cos(tilt)) == pytest.approx(0.4 - 0.2 / math.cos(tilt))


def test_steeply_tilted_legs_slip_within_the_friction_cone() -> None:
    """55 deg tilt: the belly-normal force's part along the ground exceeds mu; it is cut."""
    tilt = math.radians(55.0)
    belly = (math.sin(tilt), 0.0, math.cos(tilt))
    fx, fy, fz = leg_stance_force(0.3, (0.0, 0.0, 0.0), LEGS, belly)
    assert fz == pytest.approx(12.0 * math.cos(tilt))
    assert fx == pytest.approx(LEGS.friction_coefficient * fz) and fy == 0.0


UNIT = st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(0.05, 1)).filter(
    lambda v: math.hypot(*v) > 1e-3
)


@settings(max_examples=300, deadline=None)
@given(
    compression_m=st.floats(-0.1, 0.4),
    velocity=st.tuples(st.floats(-20, 20), st.floats(-20, 20), st.floats(-20, 20)),
    direction=UNIT,
    mu=st.floats(0.0, 2.0),
)
def test_tilted_legs_never_pull_exceed_the_cap_or_leave_the_friction_cone(
    compression_m: float, velocity: tuple, direction: tuple, mu: float
) -> None:
    legs = LegImpedance(40.0, 200.0, 20.0, mu, 190.0)
    norm = math.hypot(*direction)
    belly = tuple(c / norm for c in direction)
    fx, fy, fz = leg_stance_force(compression_m, velocity, legs, belly)
    assert all(math.isfinite(f) for f in (fx, fy, fz))
    assert fz >= 0.0
    assert math.hypot(fx, fy, fz) <= legs.force_max_n * (1.0 + 1e-12)
    assert math.hypot(fx, fy) <= mu * fz * (1.0 + 1e-12) + 1e-12
    if compression_m <= 0.0:
        assert (fx, fy, fz) == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("angle", [0.0, 90.0, math.nan, 120.0])
def test_the_cone_must_be_an_angle_between_0_and_90_deg(angle: float) -> None:
    with pytest.raises(ValueError, match="cone_half_angle_deg"):
        LegImpedance(40.0, 200.0, 20.0, 0.8, 190.0, angle)
    with pytest.raises(ValueError, match="leg_cone_half_angle_deg"):
        SimConfig(leg_cone_half_angle_deg=angle)


# --- posture about the tether axis ----------------------------------------------------------
def _roll_deg(state) -> float:
    """Roll of the body about the tether axis [deg]: the tilt of body +y out of level."""
    q = state.orientation_wxyz
    body_y_world = Rotation.from_quat([q[1], q[2], q[3], q[0]]).apply([0.0, 1.0, 0.0])
    return math.degrees(math.asin(max(-1.0, min(1.0, body_y_world[2]))))


def _standing(config: SimConfig, seconds: float, rate_rad_s=(0.6, 0.0, 0.3)) -> list:
    """A lunar robot standing crouched on its legs, kicked into a roll and a yaw spin."""
    sim = Simulator(
        MODEL,
        config,
        InitialState(position_m=(0.0, 0.0, 0.215), angular_velocity_rad_s=rate_rad_s),
    )
    states = []
    for _ in range(int(seconds / DT)):
        sim.step()
        states.append(sim.state())
    return states


def test_standing_legs_level_the_body_about_the_tether_axis() -> None:
    """The feet spread under the y limbs hold the roll a spinning, sliding robot gets."""
    states = _standing(SimConfig(gravity_m_s2=1.62, compliant_legs=True), 3.0)
    rolls = np.array([_roll_deg(s) for s in states])
    assert float(np.abs(rolls).max()) < 10.0
    assert abs(rolls[-1]) < 1.0
    assert min(float(s.mass_positions_world_m[:, 2].min()) for s in states) > 0.0
    # the moment comes from the load moved between the feet: the legs still carry the weight
    weight = 2 * MODEL.hemi_mass_kg * 1.62
    assert float(states[-1].leg_force_n[:, 2].sum()) == pytest.approx(weight, rel=0.05)


def test_without_the_feet_spread_a_standing_robot_rolls_onto_its_limbs() -> None:
    """The same kick with the levelling moment off: the two-point stance rolls over."""
    config = SimConfig(
        gravity_m_s2=1.62,
        compliant_legs=True,
        leg_roll_stiffness_nm_rad=0.0,
        leg_roll_damping_nm_s_rad=0.0,
    )
    states = _standing(config, 3.0)
    assert max(abs(_roll_deg(s)) for s in states) > 20.0


def test_roll_load_share_levels_within_the_support_polygon() -> None:
    legs = SimConfig().legs
    # rolled +y side up: load moves to the right feet (u < 0), a moment towards level
    assert roll_load_share(math.sin(0.05), 0.0, 30.0, 0.2, legs) < 0.0
    assert roll_load_share(-math.sin(0.05), 0.0, 30.0, 0.2, legs) > 0.0
    assert roll_load_share(0.0, 1.0, 30.0, 0.2, legs) < 0.0  # damping
    u = roll_load_share(math.sin(0.05), 0.0, 30.0, 0.2, legs)
    moment = 2.0 * u * 0.2 * 30.0
    assert moment == pytest.approx(-legs.roll_stiffness_nm_rad * math.sin(0.05))
    # at most the whole load on one side; nothing without load or lever
    assert roll_load_share(1.0, 0.0, 1.0, 0.2, legs) == -0.5
    assert roll_load_share(-1.0, 0.0, 1.0, 0.2, legs) == 0.5
    assert roll_load_share(0.5, 0.0, 0.0, 0.2, legs) == 0.0
    assert roll_load_share(0.5, 0.0, 10.0, 0.0, legs) == 0.0
