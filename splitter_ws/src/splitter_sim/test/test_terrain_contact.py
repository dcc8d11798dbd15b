"""Contact with a terrain (splitter_model.terrain): slopes against closed forms, steps.

A robot standing on its lumped masses on a slope of angle ``theta`` with friction
``mu`` stays (``tan theta < mu``; the regularised friction creeps at most mm/s) or
slides with the block-on-an-incline acceleration ``g (sin theta - mu cos theta)``
down the slope (the model's linear damping takes ~0.5 %). On its compliant legs,
planted feet hold it where the friction cone allows. Steps hold a mass on their top
and stop one at their walls; the compiled kernels and the pure-Python path agree.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from splitter_model.model import RobotModel
from splitter_model.terrain import Terrain
from splitter_sim.core.simulator import InitialState, SimConfig, Simulator

MODEL = RobotModel()
G_MOON = 1.62  # [m/s^2]
DT = 0.005  # [s]
STEP_FLAT = (1.5, 4.0, -1.0, 1.0, 0.2)  # [m] under hemi a's side
POSTURE_N_M = 300.0  # [N/m] the legs' ride posture measured (README "Ride height")


def _standing(config: SimConfig, lift_m: float, compiled: bool = True) -> Simulator:
    """A robot aligned with the ground's base plane, its lowest mass ``lift_m`` above it."""
    terrain = config.terrain
    wxyz = (1.0, 0.0, 0.0, 0.0)
    if terrain.slope_deg:
        xyzw = Rotation.from_matrix(terrain.ground_frame()).as_quat()
        wxyz = (xyzw[3], *xyzw[:3])
    probe = Simulator(MODEL, config, InitialState(position_m=(0, 0, 10.0), orientation_wxyz=wxyz))
    normal = np.array(terrain.normal)
    lowest = float(((probe.state().mass_positions_world_m - (0, 0, 10.0)) @ normal).min())
    start = normal * (lift_m - lowest)
    return Simulator(
        MODEL,
        config,
        InitialState(position_m=tuple(start), orientation_wxyz=wxyz),
        compiled=compiled,
    )


def _run(sim: Simulator, seconds: float) -> list:
    states = []
    for _ in range(round(seconds / DT)):
        sim.step()
        states.append(sim.state())
    return states


@pytest.mark.parametrize(("slope_deg", "mu"), [(20.0, 0.2), (20.0, 0.0), (10.0, 0.1)])
def test_a_robot_on_its_masses_slides_down_a_slope_as_a_block(slope_deg: float, mu: float) -> None:
    config = SimConfig(gravity_m_s2=G_MOON, friction_coefficient=mu, ground_slope_deg=slope_deg)
    states = _run(_standing(config, 0.001), 2.0)
    v = np.array([s.velocity_m_s for s in states])
    acceleration = (v[-1] - v[len(v) // 2]) / 1.0  # [m/s^2] over the last second
    theta = math.radians(slope_deg)
    down = np.array([-math.cos(theta), 0.0, -math.sin(theta)])
    expected = G_MOON * (math.sin(theta) - mu * math.cos(theta))
    assert float(acceleration @ down) == pytest.approx(expected, rel=0.01)
    assert np.linalg.norm(acceleration - (acceleration @ down) * down) < 0.01 * expected


def test_a_robot_on_its_masses_stays_on_a_slope_its_friction_holds() -> None:
    config = SimConfig(gravity_m_s2=G_MOON, friction_coefficient=0.8, ground_slope_deg=10.0)
    states = _run(_standing(config, 0.001), 2.0)
    assert np.linalg.norm(states[-1].velocity_m_s) < 0.005  # [m/s] creep of the regularisation


@pytest.mark.parametrize("slope_deg", [5.0, 15.0])
def test_planted_feet_hold_a_robot_on_a_slope(slope_deg: float) -> None:
    config = SimConfig(gravity_m_s2=G_MOON, compliant_legs=True, ground_slope_deg=slope_deg)
    states = _run(_standing(config, 0.3), 4.0)
    terrain = config.terrain
    lowest = min(float(terrain.signed_distance_m(s.mass_positions_world_m).min()) for s in states)
    assert lowest > 0.1  # [m] on its legs throughout
    # without sticking feet the hip damper alone lets it creep at m g sin / c_t: 0.06-0.19 m/s
    assert abs(float(states[-1].velocity_m_s[0])) < 0.01
    travel = np.linalg.norm(states[-1].position_m[:2] - states[0].position_m[:2])
    assert travel < 0.05  # [m] (creeping: 0.2-0.8 m in these 4 s)
    legs = float(np.linalg.norm(states[-1].leg_force_n, axis=1).sum())
    assert legs == pytest.approx(MODEL.total_mass_kg * G_MOON, rel=0.05)


def test_without_sticking_feet_the_robot_creeps_down_the_slope() -> None:
    config = SimConfig(
        gravity_m_s2=G_MOON, compliant_legs=True, ground_slope_deg=10.0, leg_hold_stiffness_n_m=0.0
    )
    states = _run(_standing(config, 0.3), 4.0)
    assert float(states[-1].velocity_m_s[0]) < -0.05  # [m/s] downhill (-x)


@pytest.mark.parametrize("compiled", [True, False])
def test_a_robot_dropped_across_a_step_rests_on_its_top_and_the_ground(compiled: bool) -> None:
    config = SimConfig(gravity_m_s2=G_MOON, ground_steps_m=STEP_FLAT)
    states = _run(_standing(config, 0.3, compiled), 3.0)
    end = states[-1]
    z = end.mass_positions_world_m[:, 2]
    assert np.linalg.norm(end.velocity_m_s) < 1e-3
    assert float(z[:5].min()) == pytest.approx(0.2, abs=1e-3)  # hemi a on the step's top
    assert float(z[5:].min()) == pytest.approx(0.0, abs=1e-3)  # hemi b on the ground


def test_compiled_and_python_agree_on_a_sloped_terrain_with_a_step() -> None:
    config = SimConfig(
        gravity_m_s2=G_MOON,
        compliant_legs=True,
        ground_slope_deg=8.0,
        ground_slope_azimuth_deg=20.0,
        ground_steps_m=STEP_FLAT,
    )
    a = _run(_standing(config, 0.5, True), 1.5)
    b = _run(_standing(config, 0.5, False), 1.5)
    np.testing.assert_allclose(a[-1].position_m, b[-1].position_m, atol=1e-9)
    np.testing.assert_allclose(a[-1].contact_force_n, b[-1].contact_force_n, atol=1e-6)


def test_a_sliding_robot_is_stopped_by_a_step_wall() -> None:
    config = SimConfig(
        gravity_m_s2=G_MOON, friction_coefficient=0.0, ground_steps_m=(3.5, 5.0, -1, 1, 0.3)
    )
    probe = Simulator(MODEL, config, InitialState(position_m=(0, 0, 10.0)))
    lowest = float(probe.state().mass_positions_world_m[:, 2].min()) - 10.0
    sim = Simulator(
        MODEL,
        config,
        InitialState(position_m=(0.0, 0.0, 0.0005 - lowest), velocity_m_s=(0.5, 0, 0)),
    )
    states = _run(sim, 4.0)
    reach = max(float(s.mass_positions_world_m[:, 0].max()) for s in states)
    assert reach < 3.5 + 0.02  # [m] it never went more than 2 cm into the wall
    assert float(states[-1].velocity_m_s[0]) < 0.0  # it bounced back (no friction)


def test_level_terrain_parameters_give_the_level_ground_exactly() -> None:
    a = _run(_standing(SimConfig(gravity_m_s2=G_MOON, compliant_legs=True), 0.3), 0.5)
    config = SimConfig(gravity_m_s2=G_MOON, compliant_legs=True, ground_slope_azimuth_deg=45.0)
    assert config.terrain == Terrain(0.0, 45.0)
    b = _run(_standing(config, 0.3), 0.5)
    np.testing.assert_array_equal(a[-1].position_m, b[-1].position_m)


def _slide(slope_deg: float, hold_n_m: float, seconds: float = 6.0) -> list:
    """A robot standing on its legs sliding at 1.5 m/s down a slope rising towards -x."""
    config = SimConfig(
        gravity_m_s2=G_MOON,
        compliant_legs=True,
        ground_slope_deg=slope_deg,
        ground_slope_azimuth_deg=180.0,
        leg_hold_stiffness_n_m=hold_n_m,
    )
    standing = _standing(config, 0.2)
    frame = config.terrain.ground_frame()
    state = standing.state()
    sim = Simulator(
        MODEL,
        config,
        InitialState(
            position_m=tuple(state.position_m),
            velocity_m_s=tuple(frame @ (1.5, 0.0, 0.0)),
            orientation_wxyz=tuple(state.orientation_wxyz),
        ),
    )
    return _run(sim, seconds)


@pytest.mark.parametrize("slope_deg", [0.0, 8.0])
def test_planted_feet_stop_a_slide_within_the_coulomb_distance(slope_deg: float) -> None:
    states = _slide(slope_deg, SimConfig().leg_hold_stiffness_n_m)
    travel = float(np.linalg.norm(states[-1].position_m - states[0].position_m))
    theta = math.radians(slope_deg)
    deceleration = G_MOON * (0.8 * math.cos(theta) - math.sin(theta))  # [m/s^2]
    assert travel == pytest.approx(1.5**2 / (2.0 * deceleration), rel=0.05)
    assert abs(float(states[-1].velocity_m_s[0])) < 0.005  # at rest, held


def test_without_planted_feet_a_downhill_slide_never_stops() -> None:
    states = _slide(8.0, 0.0)
    assert float(np.linalg.norm(states[-1].velocity_m_s[:2])) > 0.05  # [m/s] still creeping


def _slide_towards_a_step(posture_n_m: float, step_m: float = 0.12) -> list:
    """A robot crouched on its legs (lowest mass 3.3 cm up, the spring's rest) sliding at
    2 m/s along +x; a ``step_m`` step's wall 1 m ahead of hemi a's lowest mass."""
    config = SimConfig(
        gravity_m_s2=G_MOON,
        compliant_legs=True,
        leg_posture_stiffness_n_m=posture_n_m,
        ground_steps_m=(3.8, 20.0, -5.0, 5.0, step_m),
    )
    crouched = _standing(config, 0.033)
    state = crouched.state()
    sim = Simulator(
        MODEL,
        config,
        InitialState(position_m=tuple(state.position_m), velocity_m_s=(2.0, 0.0, 0.0)),
    )
    return _run(sim, 3.0)


def test_a_sliding_hemi_rides_over_a_step_its_crouch_would_strike() -> None:
    """The ride posture (splitter_sim.core.legs "Ride height") stands a sliding hemi up, so
    its lowest mass clears a 12 cm step; crouched (no posture) a limb tip strikes it."""
    riding = _slide_towards_a_step(POSTURE_N_M)
    crouched = _slide_towards_a_step(0.0)
    peak_riding = max(float(np.linalg.norm(s.contact_force_n, axis=1).max()) for s in riding)
    peak_crouched = max(float(np.linalg.norm(s.contact_force_n, axis=1).max()) for s in crouched)
    assert peak_riding <= 190.0 + 1e-9  # [N] only the legs: the cap
    assert peak_crouched > 196.133  # [N] a tip struck the wall: over the limbs' limit
    lowest_over_step = min(
        float(s.mass_positions_world_m[:5, 2].min())
        for s in riding
        if float(s.mass_positions_world_m[:5, 0].max()) > 3.8
    )
    assert lowest_over_step > 0.12  # [m] hemi a's masses passed above the step's top
    assert float(riding[-1].position_m[0]) > 1.0  # [m] and the robot slid on onto it


def _jump_from_standing(posture_n_m: float, lift_m: float) -> tuple[list, float]:
    """A lunar robot standing still on its legs (placed ``lift_m`` up), then commanded the
    second jump's push (160 N forward, 320 N up, both hemis); its states and the push's
    start [s]."""
    config = SimConfig(
        gravity_m_s2=G_MOON, compliant_legs=True, leg_posture_stiffness_n_m=posture_n_m
    )
    sim = _standing(config, lift_m)
    _run(sim, 2.0)  # settles at its standing height
    sim.command_jump_force((160.0, 0.0, 320.0), "auto")
    states = _run(sim, 1.5)
    pushing = [i for i, s in enumerate(states) if float(np.abs(s.thrust_force_n).sum()) > 0.0]
    return states, pushing[0] * DT


def test_a_standing_robot_crouches_then_pushes_the_whole_stroke() -> None:
    """The legs stand the robot at the ride height, crouch (feet loaded) before the push
    and push from the crouch: at least the lift-off speed of a crouched start (the
    sinking adds a little, a counter-movement), not that of a push from standing."""
    states, start_s = _jump_from_standing(POSTURE_N_M, 0.2)
    lowest = [float(s.mass_positions_world_m[:, 2].min()) for s in states]
    assert 0.35 < start_s < 1.0  # [s] the crouch before the push
    at_start = round(start_s / DT)
    assert lowest[0] == pytest.approx(0.2, abs=0.01)  # [m] stood at the ride height
    assert lowest[at_start] < 0.03  # [m] and crouched before pushing
    loaded = [float(np.linalg.norm(s.contact_force_n, axis=1).min()) for s in states[:at_start]]
    assert min(loaded) > 5.0  # [N] each hemi's feet on the ground through the crouch
    liftoff_vx = max(float(s.velocity_m_s[0]) for s in states)
    # the crouched robot without a posture (its spring's rest, 3.3 cm up) pushes the same
    crouched, crouched_start = _jump_from_standing(0.0, 0.033)
    assert crouched_start == 0.0
    crouched_vx = max(float(s.velocity_m_s[0]) for s in crouched)
    assert crouched_vx <= liftoff_vx < 1.1 * crouched_vx
