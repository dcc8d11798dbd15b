"""The simulator against physics: conservation laws and closed-form solutions.

Each test runs the real :class:`Simulator` at the paper's step (5 ms, RK4) and
compares with what mechanics says must happen. Tolerances are those of the
issue; where a check could pass for the wrong reason, a second run shows it
failing when the physics is deliberately broken.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from scipy.special import ellipk

from splitter_model.actuators import TETHER_INDEX
from splitter_model.kinematics import joint_positions_from_radii
from splitter_model.model import GRAVITY_PRESETS, RobotModel
from splitter_sim.core.legs import stroke_left_after_stop_m
from splitter_sim.core.simulator import InitialState, SimConfig, Simulator

MODEL = RobotModel()
PAPER_W0 = (-0.3, -0.9, 0.9)  # [rad/s] Table I
DT = 0.005  # [s]


def _relative(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(np.asarray(a) - np.asarray(b)) / np.linalg.norm(b))


def _flight(w0=PAPER_W0, radii=(2.8, 0.2, 0.2), model: RobotModel = MODEL, **kwargs) -> Simulator:
    return Simulator(
        model,
        SimConfig(ground_contact=False),
        InitialState(position_m=(0.0, 0.0, 10.0), angular_velocity_rad_s=w0, radii_m=radii),
        **kwargs,
    )


def test_torque_free_constant_geometry_conserves_momentum_and_energy_for_20_s() -> None:
    # Asymmetric geometry (three distinct moments) so the body tumbles.
    sim = _flight(w0=(0.4, -0.9, 0.7), radii=(2.2, 0.33, 0.14))
    start = sim.state()
    worst_h = worst_e = 0.0
    for k in range(int(20.0 / DT)):
        sim.step()
        if k % 50 == 49:
            s = sim.state()
            worst_h = max(
                worst_h, _relative(s.angular_momentum_world, start.angular_momentum_world)
            )
            worst_e = max(worst_e, abs(s.kinetic_energy_j / start.kinetic_energy_j - 1.0))
    assert sim.time_ns == 20_000_000_000
    assert worst_h < 1e-9
    assert worst_e < 1e-9
    # The body did tumble: the body-frame angular velocity changed a lot.
    assert _relative(sim.state().angular_velocity_rad_s, start.angular_velocity_rad_s) > 0.1


def _morph(sim: Simulator) -> tuple[list, list]:
    """Reel the tether in and move the limbs (two commands), then hold; sample states."""
    first = joint_positions_from_radii(MODEL, (2.3, 0.3, 0.13))
    second = joint_positions_from_radii(MODEL, (2.6, 0.16, 0.26))
    states = [sim.state()]
    sim.command_joints(first)
    for k in range(int(3.0 / DT)):
        if k == int(1.4 / DT):
            sim.command_joints(second)
        sim.step()
        states.append(sim.state())
    return states, [first, second]


HEMI_INERTIA = (0.03, 0.045, 0.04)  # [kg m^2] a 3 kg box of 0.33 x 0.22 x 0.26 m


@pytest.mark.parametrize(
    "hemi_inertia", [(0.0, 0.0, 0.0), HEMI_INERTIA], ids=["point bodies", "hemi inertia"]
)
def test_morphing_conserves_momentum_and_energy_changes_by_actuator_work(hemi_inertia) -> None:
    states, (_, second) = _morph(_flight(hemi_inertia_kg_m2=hemi_inertia))
    start, end = states[0], states[-1]
    # The joints really moved, ended at rest on the last command, and changed the energy.
    assert max(np.abs(s.joint_velocity).max() for s in states) > 1.0
    np.testing.assert_array_equal(end.joint_position, second)
    assert not end.joint_velocity.any()
    delta_e = end.rotational_energy_j - start.rotational_energy_j
    assert abs(delta_e) > 0.05 * start.rotational_energy_j
    h_error = max(_relative(s.angular_momentum_world, start.angular_momentum_world) for s in states)
    assert h_error < 1e-9
    # At rest the kinetic energy about the COM is 1/2 w'Iw, the paper's rotational energy.
    assert end.kinetic_energy_about_com_j == pytest.approx(end.rotational_energy_j, rel=1e-12)
    assert abs(delta_e - end.actuator_work_j) < 1e-6 * abs(delta_e)
    # Throughout (limbs moving): kinetic energy about the COM changes by the work done.
    for s in states[1:]:
        change = s.kinetic_energy_about_com_j - start.kinetic_energy_about_com_j
        assert abs(change - s.actuator_work_j) < 1e-6 * abs(delta_e)


def test_hemi_bodies_add_their_own_inertia_to_the_tensor() -> None:
    """Each hemi body turns rigidly with the base, so its own principal moments add to the
    ten masses' tensor at every shape, moving or not (parallel axes: the bodies' centres
    are the lumped masses); the momentum answers to the whole tensor."""
    states = _morph(_flight(hemi_inertia_kg_m2=HEMI_INERTIA))[0]
    points = _morph(_flight())[0]
    for k in range(0, len(states), 40):
        with_bodies, without = states[k], points[k]
        np.testing.assert_array_equal(with_bodies.joint_position, without.joint_position)
        np.testing.assert_allclose(
            with_bodies.inertia_tensor_kg_m2 - without.inertia_tensor_kg_m2,
            2.0 * np.diag(HEMI_INERTIA),
            atol=1e-12,
        )
    start = states[0]  # at rest: h = I w, with the bodies' own inertia in I
    world_from_base = Rotation.from_quat(np.roll(np.array(start.orientation_wxyz), -1))
    np.testing.assert_allclose(
        world_from_base.inv().apply(np.array(start.angular_momentum_world)),
        start.inertia_tensor_kg_m2 @ np.asarray(PAPER_W0),
        rtol=1e-12,
    )
    # a different body: the same morphing turns it differently
    assert _relative(states[-1].angular_velocity_rad_s, points[-1].angular_velocity_rad_s) > 1e-3


def test_reel_power_is_tension_times_reel_in_speed() -> None:
    """Only the tether moves: the actuator power is T * (-d(tether)/dt), two code paths."""
    sim = _flight(w0=(0.1, 1.0, -0.2))
    sim.command_joints(joint_positions_from_radii(MODEL, (2.0, 0.2, 0.2)))
    checked = 0
    for _ in range(300):
        sim.step()
        s = sim.state()
        reel_speed = -s.joint_velocity[TETHER_INDEX]  # [m/s] > 0 reeling in
        assert s.actuator_power_w == pytest.approx(s.tether_tension_n * reel_speed, abs=1e-9)
        checked += reel_speed > 0.5
    assert checked > 100


def test_joint_efforts_do_the_actuator_work() -> None:
    """Limb torques and tether tension, against the actuator power (a second code path):
    sum tau qd (limbs) - T d(tether)/dt = P, while limbs and tether all move."""
    states, _ = _morph(_flight())
    moving = 0
    for s in states[1:]:
        qd, effort = s.joint_velocity, s.joint_effort
        power = float(effort[:TETHER_INDEX] @ qd[:TETHER_INDEX]) - effort[TETHER_INDEX] * float(
            qd[TETHER_INDEX]
        )
        assert power == pytest.approx(s.actuator_power_w, abs=1e-9 * 100.0)
        assert effort[TETHER_INDEX] == s.tether_tension_n
        moving += abs(s.actuator_power_w) > 1.0
    assert moving > 50


def test_steady_spin_efforts_hold_the_masses_on_their_circles() -> None:
    """A rigid spin w about y: the tether holds a hemi's 9 kg on its circle,
    T = (m_x + 2 m_y + 2 m_z) r_x w^2; the z limbs' joints hold their masses, so
    J^T of the centripetal force is their torque (closed form)."""
    from splitter_model.joints import limb_joints, limbs_along
    from splitter_model.kinematics import limb_jacobian

    w, radii = 1.1, (2.0, 0.25, 0.3)  # [rad/s], [m]
    s = _flight(w0=(0.0, w, 0.0), radii=radii).state()
    hemi = MODEL.body_mass_kg + 2.0 * MODEL.limb_mass_y_kg + 2.0 * MODEL.limb_mass_z_kg
    assert s.joint_effort[TETHER_INDEX] == pytest.approx(hemi * radii[0] * w**2, rel=1e-9)
    for limb in limbs_along("z"):
        q = s.joint_position[limb_joints(limb)]
        sign = 1.0 if limb < 4 else -1.0
        up = 1.0 if limb % 4 == 2 else -1.0
        tip = np.array([sign * radii[0], 0.0, up * radii[2]])
        force = MODEL.limb_mass_z_kg * (-(w**2) * np.array([tip[0], 0.0, tip[2]]))
        expected = limb_jacobian(MODEL, limb, q).T @ force
        np.testing.assert_allclose(s.joint_effort[limb_joints(limb)], expected, atol=1e-9)
        assert np.abs(expected).max() > 0.1


def test_flipped_gyroscopic_sign_fails_the_momentum_check() -> None:
    """The paper's sign error: the energy balance cannot see it, world H does."""
    states, _ = _morph(_flight(gyroscopic_sign=1.0))
    start, end = states[0], states[-1]
    h_error = max(_relative(s.angular_momentum_world, start.angular_momentum_world) for s in states)
    assert h_error > 1e-2  # the 1e-9 check of the test above fails by 7 orders
    # Gyroscopic forces do no work (w . (w x L) = 0): the energy balance still closes.
    delta_e = end.rotational_energy_j - start.rotational_energy_j
    assert abs(delta_e - end.actuator_work_j) < 1e-6 * abs(delta_e)


def _dzhanibekov_period(inertia: np.ndarray, w0: np.ndarray) -> float:
    """Full period of the torque-free Euler equations (Landau & Lifshitz section 37)."""
    i1, i2, i3 = inertia
    energy2 = float(np.sum(inertia * w0**2))  # 2E
    momentum2 = float(np.sum((inertia * w0) ** 2))  # H^2
    if momentum2 < energy2 * i2:  # polhode around the smallest axis: swap 1 and 3
        i1, i3 = i3, i1
    rate = math.sqrt((i3 - i2) * (momentum2 - energy2 * i1) / (i1 * i2 * i3))
    m = (i2 - i1) * (energy2 * i3 - momentum2) / ((i3 - i2) * (momentum2 - energy2 * i1))
    return 4.0 * float(ellipk(m)) / rate


def test_intermediate_axis_flips_with_the_closed_form_period() -> None:
    radii = (1.0, 0.35, 0.12)  # Ixx < Iyy < Izz: y is the intermediate axis
    w0 = np.array([0.05, 3.0, 0.05])
    sim = _flight(w0=w0, radii=radii)
    inertia = sim.state().principal_inertia_kg_m2
    assert inertia[0] < inertia[1] < inertia[2]
    expected = _dzhanibekov_period(inertia, w0)
    crossings = []
    t_prev, wy_prev = 0.0, w0[1]
    while len(crossings) < 3:
        sim.step()
        s = sim.state()
        t, wy = s.t_ns * 1e-9, s.angular_velocity_rad_s[1]
        if wy_prev > 0.0 >= wy:  # downward zero crossing of w_y: a flip
            crossings.append(t_prev + (t - t_prev) * wy_prev / (wy_prev - wy))
        t_prev, wy_prev = t, wy
        assert t < 5.0 * expected, "no flips"
    periods = np.diff(crossings)
    assert periods == pytest.approx([expected, expected], rel=0.01)


def test_axisymmetric_body_precesses_as_the_closed_form() -> None:
    sim = _flight()  # paper Table I: r_y = r_z, so Iyy = Izz (symmetric about x)
    start = sim.state()
    i_a, i_t, _ = start.principal_inertia_kg_m2
    w0 = np.array(PAPER_W0)
    h_world = start.angular_momentum_world
    h_norm = float(np.linalg.norm(h_world))
    axis0 = Rotation.from_quat(np.roll(start.orientation_wxyz, -1)).apply([1.0, 0.0, 0.0])
    body_rate = (i_t - i_a) * w0[0] / i_t  # [rad/s] of w_perp in the body
    for _ in range(int(10.0 / DT)):
        sim.step()
    s = sim.state()
    t = s.t_ns * 1e-9
    c, sn = math.cos(body_rate * t), math.sin(body_rate * t)
    expected_w = [w0[0], w0[1] * c + w0[2] * sn, w0[2] * c - w0[1] * sn]
    np.testing.assert_allclose(s.angular_velocity_rad_s, expected_w, atol=1e-9)
    # In the world the symmetry axis cones about H at |H| / I_t.
    cone = Rotation.from_rotvec(h_world / h_norm * h_norm / i_t * t)
    axis = Rotation.from_quat(np.roll(s.orientation_wxyz, -1)).apply([1.0, 0.0, 0.0])
    np.testing.assert_allclose(axis, cone.apply(axis0), atol=1e-8)


def test_free_fall_follows_the_damped_parabola() -> None:
    g = GRAVITY_PRESETS["moon"]
    sim = Simulator(
        MODEL,
        SimConfig(gravity_m_s2=g, ground_contact=True),
        InitialState(position_m=(1.0, -2.0, 30.0), velocity_m_s=(2.0, 0.5, 3.0)),
    )
    beta = MODEL.damping_coefficient / MODEL.total_mass_kg  # [1/s]
    v0 = np.array([2.0, 0.5, 3.0])
    v_inf = np.array([0.0, 0.0, -g / beta])  # [m/s] terminal velocity of M dv/dt = -B v - M g
    worst = 0.0
    for _ in range(int(3.0 / DT)):
        sim.step()
        s = sim.state()
        t = s.t_ns * 1e-9
        # x0 + v0 (1 - e^-bt) / b + v_inf (t - (1 - e^-bt) / b), written without cancellation
        decay = -math.expm1(-beta * t) / beta
        lag = (beta * t + math.expm1(-beta * t)) / beta
        expected = np.array([1.0, -2.0, 30.0]) + v0 * decay + v_inf * lag
        worst = max(worst, float(np.abs(s.position_m - expected).max()))
        assert not s.in_contact.any()
        # Free fall: an IMU measures no specific force except the tiny drag.
        assert np.linalg.norm(s.linear_acceleration_m_s2) < 1e-3
    assert worst < 1e-9
    # Without damping it is the textbook parabola.
    t = 3.0
    assert s.position_m[2] == pytest.approx(30.0 + 3.0 * t - 0.5 * g * t * t, abs=1e-3)


@pytest.mark.parametrize("gravity", ["moon", "earth"])
def test_dropped_robot_comes_to_rest_with_bounded_penetration_inside_the_cone(
    gravity: str,
) -> None:
    g = GRAVITY_PRESETS[gravity]
    config = SimConfig(gravity_m_s2=g)
    drop_height = 0.5  # [m] of the lowest mass above the ground
    tilt = Rotation.from_euler("xyz", [25.0, 4.0, 10.0], degrees=True)
    initial = InitialState(
        position_m=(0.0, 0.0, 3.0),
        velocity_m_s=(0.4, -0.2, 0.0),
        orientation_wxyz=np.roll(tilt.as_quat(), 1),
        angular_velocity_rad_s=(0.3, 0.05, -0.1),
    )
    lowest = Simulator(MODEL, config, initial).state().mass_positions_world_m[:, 2].min()
    sim = Simulator(
        MODEL, config, replace(initial, position_m=(0.0, 0.0, 3.0 - lowest + drop_height))
    )
    m_total = MODEL.total_mass_kg
    k = config.contact_stiffness_n_m
    e0 = sim.state().kinetic_energy_j + m_total * g * drop_height
    # Energy bound: one spring could at most store everything the drop releases.
    weight = m_total * g
    penetration_bound = (weight + math.sqrt(weight**2 + 2.0 * k * e0)) / k
    worst_penetration = 0.0
    touched = False
    for _ in range(int(8.0 / DT)):
        sim.step()
        s = sim.state()
        worst_penetration = max(worst_penetration, -float(s.mass_positions_world_m[:, 2].min()))
        touched |= bool(s.in_contact.any())
        f = s.contact_force_n
        tangential = np.hypot(f[:, 0], f[:, 1])
        assert np.all(f[:, 2] >= 0.0)
        assert np.all(tangential <= config.friction_coefficient * f[:, 2] + 1e-9)
    assert touched
    assert worst_penetration < penetration_bound
    assert np.linalg.norm(s.velocity_m_s) < 1e-6
    assert np.linalg.norm(s.angular_velocity_rad_s) < 1e-6
    # At rest the ground carries the weight, shared by the feet: penetration M g / (n k).
    assert s.contact_force_n[:, 2].sum() == pytest.approx(weight, rel=1e-6)
    depths = -s.mass_positions_world_m[:, 2]
    assert depths[depths > 0].sum() == pytest.approx(weight / k, rel=1e-6)
    assert int(np.sum(depths > 0.0)) >= 3  # on a tripod or more, not balanced on a line


def _standing(config: SimConfig) -> Simulator:
    """Settled on four feet: rolled 45 deg about x, the y_neg and z_neg limbs down."""
    roll = np.roll(Rotation.from_euler("x", 45.0, degrees=True).as_quat(), 1)
    sim = Simulator(
        MODEL,
        config,
        InitialState(position_m=(0.0, 0.0, 0.2 * math.sqrt(0.5)), orientation_wxyz=roll),
    )
    for _ in range(400):
        sim.step()
    s = sim.state()
    assert np.linalg.norm(s.velocity_m_s) < 1e-6 and s.in_contact.all()
    assert int(np.sum(s.mass_positions_world_m[:, 2] < 0.0)) == 4
    return sim


def test_sliding_robot_decelerates_at_mu_g() -> None:
    g = GRAVITY_PRESETS["earth"]
    config = SimConfig(gravity_m_s2=g)
    s0 = _standing(config).state()
    sim2 = Simulator(
        MODEL,
        config,
        InitialState(
            position_m=s0.position_m,
            velocity_m_s=(2.0, 0.0, 0.0),
            orientation_wxyz=s0.orientation_wxyz,
        ),
    )
    v = []
    for _ in range(40):
        sim2.step()
        v.append(sim2.state().velocity_m_s[0])
    decel = -(v[-1] - v[9]) / (30 * DT)
    assert decel == pytest.approx(config.friction_coefficient * g, rel=0.02)


def test_jump_thrust_gives_impulse_over_mass_take_off_velocity() -> None:
    """The paper's lunar sizing: 21.7 m/s^2 over the 0.4 m stroke -> 4.0 m/s take-off."""
    g = GRAVITY_PRESETS["moon"]
    sim = _standing(SimConfig(gravity_m_s2=g))
    m_total = MODEL.total_mass_kg
    accel = 21.7  # [m/s^2] paper section IV
    force = np.array([0.0, 0.0, m_total * (accel + g)])
    steps = round(4.0 / accel / DT)
    sim.command_jump_force(force)
    for _ in range(steps):
        sim.step()
        assert sim.state().in_thrust_range.all()
    sim.command_jump_force((0.0, 0.0, 0.0))
    take_off = sim.state()
    predicted = (force[2] - m_total * g) * steps * DT / m_total
    assert take_off.velocity_m_s[2] == pytest.approx(predicted, rel=0.02)
    assert take_off.velocity_m_s[2] == pytest.approx(4.0, rel=0.02)
    # Split over both hemis: no torque, no spin.
    assert np.linalg.norm(take_off.angular_velocity_rad_s) < 1e-9
    assert not take_off.in_contact.any()


def test_thrust_through_one_hemi_spins_the_robot() -> None:
    # Feet 0.15 m above the ground: within the 0.4 m stroke, never touching.
    sim = Simulator(MODEL, SimConfig(gravity_m_s2=0.0), InitialState(position_m=(0.0, 0.0, 0.35)))
    force = np.array([40.0, 0.0, 40.0])
    sim.command_jump_force(force, hemi="b")
    steps = 40
    angular_impulse = np.zeros(3)
    for _ in range(steps):
        s = sim.state()
        lever = s.mass_positions_world_m[5] - s.position_m  # hemi b body
        assert s.thrust_force_n[1] == pytest.approx(force)
        assert not s.thrust_force_n[0].any()
        # The thrust is the ground's reaction on hemi b's legs: its contact force, applied
        # at the hemi body (no moment about it); no lumped mass touches the ground.
        np.testing.assert_array_equal(s.contact_force_n[1], force)
        assert not s.contact_force_n[0].any() and not s.contact_torque_n_m.any()
        assert s.in_contact.tolist() == [False, True]
        assert s.mass_positions_world_m[:, 2].min() > 0.0
        angular_impulse += np.cross(lever, force) * DT
        sim.step()
    s = sim.state()
    # Impulse over mass (the 1e-5 is the paper's linear damping b = 0.001 N s/m).
    np.testing.assert_allclose(s.velocity_m_s, force * steps * DT / MODEL.total_mass_kg, rtol=1e-5)
    # Angular momentum equals the angular impulse of the thrust (rectangle rule: 1e-2).
    np.testing.assert_allclose(s.angular_momentum_world, angular_impulse, rtol=2e-2)
    assert s.angular_velocity_rad_s[1] > 0.0  # hemi b at -x pushed up: spin about +y


def _lunar_drop(
    compliant_legs: bool, speed_m_s: float = 3.0, model: RobotModel = MODEL, **legs: bool
) -> tuple[SimConfig, list]:
    """Level, the lowest masses 0.45 m above the ground, ``speed_m_s`` down; 10 s of states."""
    config = SimConfig(gravity_m_s2=1.62, compliant_legs=compliant_legs, **legs)
    probe = Simulator(model, config, InitialState(position_m=(0.0, 0.0, 10.0)))
    lowest = float(probe.state().mass_positions_world_m[:, 2].min()) - 10.0  # [m] from the COM
    sim = Simulator(
        model,
        config,
        InitialState(position_m=(0.0, 0.0, 0.45 - lowest), velocity_m_s=(0.0, 0.0, -speed_m_s)),
    )
    states = []
    for _ in range(int(10.0 / DT)):
        sim.step()
        states.append(sim.state())
    return config, states


def test_lunar_drop_onto_compliant_legs_stays_within_their_force_limit() -> None:
    """The legs stop 3 m/s within their 0.4 m stroke at their 190 N cap, the masses clear."""
    config, states = _lunar_drop(compliant_legs=True)
    weight = MODEL.total_mass_kg * config.gravity_m_s2  # [N]
    peak = max(float(np.linalg.norm(s.contact_force_n, axis=1).max()) for s in states)
    assert config.leg_force_max_n - 1.0 <= peak <= config.leg_force_max_n + 2.0  # at the cap
    for s in states:
        # Only the legs touch: the lumped masses stay above the ground, every force is the
        # legs' (normal, up, at the hemi body).
        assert s.mass_positions_world_m[:, 2].min() > 0.0
        assert np.all(s.contact_force_n[:, 2] >= 0.0) and not s.contact_torque_n_m.any()
    assert max(float(s.hemi_acceleration_g.max()) for s in states) < 2.5  # [G] 190 N / 9 kg
    # At rest: standing crouched on the legs, which carry the weight, evenly.
    end = states[-1]
    assert np.linalg.norm(end.velocity_m_s) < 0.01
    assert np.linalg.norm(end.angular_velocity_rad_s) < 1e-9
    assert end.in_contact.all()
    np.testing.assert_allclose(end.contact_force_n[:, 2], [weight / 2, weight / 2], rtol=0.01)
    assert 0.0 < end.mass_positions_world_m[:, 2].min() < config.thrust_stroke_m
    # The legs' load cells carry the same weight, and only they: their force is the
    # contact force (no lumped mass touches); the rigid drop's masses are not seen by them.
    np.testing.assert_allclose(end.leg_force_n, end.contact_force_n, atol=1e-12)
    peak_legs = max(float(np.linalg.norm(s.leg_force_n, axis=1).max()) for s in states)
    assert peak_legs == pytest.approx(peak, rel=1e-12)
    # The same drop without the legs: the masses hit the ground, far above the limbs' limit.
    _, rigid = _lunar_drop(compliant_legs=False)
    assert max(float(np.linalg.norm(s.contact_force_n, axis=1).max()) for s in rigid) > 1000.0
    assert min(float(s.mass_positions_world_m[:, 2].min()) for s in rigid) < 0.0
    assert not any(s.leg_force_n.any() for s in rigid)


def test_the_legs_spend_their_whole_stroke_on_a_touchdown_the_damper_cannot_stop() -> None:
    """3.88 m/s down: a constant 190 N stops a 9 kg hemi within the 0.4 m stroke
    (sqrt(2 s (F / m - g)) = 3.95 m/s), the damper alone (saturated only above 0.95 m/s)
    from 3.86 m/s at most: with the whole-stroke stop the masses clear the ground, without
    it they strike it, far above the limbs' limit."""
    config, states = _lunar_drop(compliant_legs=True, speed_m_s=3.88)
    assert config.leg_full_stroke_stop
    peak = max(float(np.linalg.norm(s.contact_force_n, axis=1).max()) for s in states)
    assert peak <= config.leg_force_max_n + 1e-9
    assert min(float(s.mass_positions_world_m[:, 2].min()) for s in states) > 0.0
    _, damper = _lunar_drop(compliant_legs=True, speed_m_s=3.88, leg_full_stroke_stop=False)
    assert min(float(s.mass_positions_world_m[:, 2].min()) for s in damper) < 0.0
    assert max(float(np.linalg.norm(s.contact_force_n, axis=1).max()) for s in damper) > 196.0


@pytest.mark.parametrize("mass_scale", [0.94, 1.06])
def test_a_robot_not_the_nominal_one_comes_to_rest_on_the_whole_stroke_legs(
    mass_scale: float,
) -> None:
    """The whole-stroke stop computes with the nominal 9 kg hemi. At rest it must not hold
    that weight against the robot's own (it once switched on and off with the sign of the
    speed: 12.3 / 14.7 N, and the gait never saw the robot at rest)."""
    model = replace(
        MODEL,
        body_mass_kg=MODEL.body_mass_kg * mass_scale,
        limb_mass_y_kg=MODEL.limb_mass_y_kg * mass_scale,
        limb_mass_z_kg=MODEL.limb_mass_z_kg * mass_scale,
    )
    config, states = _lunar_drop(compliant_legs=True, model=model)
    assert config.leg_full_stroke_stop
    last = states[-int(2.0 / DT) :]  # the last 2 s, at rest
    force = np.array([s.contact_force_n[:, 2] for s in last])  # [N] per hemi
    weight = model.total_mass_kg * config.gravity_m_s2  # [N]
    assert np.ptp(force, axis=0).max() < 0.05
    np.testing.assert_allclose(force[-1], [weight / 2, weight / 2], rtol=0.01)
    assert max(abs(float(s.velocity_m_s[2])) for s in last) < 0.01  # [m/s] the spring settles


@pytest.mark.parametrize("speed_m_s", [3.0, 3.63])
def test_no_leg_stop_keeps_more_stroke_than_the_cap_all_the_way(speed_m_s: float) -> None:
    """Where a touchdown has stopped, the lowest mass is no higher above the ground than
    the stroke a stop at the cap all the way leaves (``stroke_left_after_stop_m``): the
    clearance a step must stay under (the jumping campaign's step range)."""
    config, states = _lunar_drop(compliant_legs=True, speed_m_s=speed_m_s)
    entry_m_s = math.sqrt(speed_m_s**2 + 2.0 * config.gravity_m_s2 * 0.05)  # [m/s] at 0.4 m
    hemi_kg = MODEL.hemi_mass_kg
    bound_m = stroke_left_after_stop_m(
        entry_m_s, hemi_kg, config.leg_force_max_n, config.gravity_m_s2, config.thrust_stroke_m
    )
    assert 0.0 < bound_m < config.thrust_stroke_m
    touched = next(i for i, s in enumerate(states) if s.in_contact.any())
    stopped = next(i for i in range(touched, len(states)) if states[i].velocity_m_s[2] > -0.01)
    lowest_m = float(states[stopped].mass_positions_world_m[:, 2].min())
    peak = max(float(np.linalg.norm(s.contact_force_n, axis=1).max()) for s in states)
    assert peak <= config.leg_force_max_n + 1e-9
    assert 0.0 < lowest_m <= bound_m


@pytest.mark.parametrize("compiled", [True, False])
def test_joints_at_rest_after_a_move_report_the_rigid_spin(compiled: bool) -> None:
    """Once the limbs stop, tension, hemi acceleration and power are those of a rigid spin.

    A move ends on a braking step; the steps after it must not keep its accelerations
    (they once did: a tension 8.6 N below the centripetal load, for as long as the
    joints rested, in a random-tumble campaign).
    """
    sim = _flight(w0=(0.0, 1.28, 0.0), compiled=compiled)
    assert sim.compiled == compiled
    sim.command_joints(joint_positions_from_radii(MODEL, (2.8, 0.35, 0.3)))
    moved = rest_checks = 0
    was_moving = False
    for _ in range(int(2.0 / DT)):
        sim.step()
        s = sim.state()
        stopping, was_moving = was_moving, bool(s.joint_velocity.any())
        if was_moving or stopping:  # moving, or the braking step just ended (its left limit)
            moved += 1
            continue
        w, r_x = s.angular_velocity_rad_s, s.radii_m[0]
        centripetal = r_x * (w[1] ** 2 + w[2] ** 2)  # [m/s^2] of each hemi body
        assert s.tether_tension_n == pytest.approx(MODEL.hemi_mass_kg * centripetal, rel=1e-9)
        assert s.actuator_power_w == pytest.approx(0.0, abs=1e-9)
        rest_checks += 1
    assert moved > 10
    assert rest_checks > 100


def test_tether_tension_is_the_centripetal_load_of_a_hemi() -> None:
    sim = _flight(w0=(0.0, 1.28, 0.0))
    s = sim.state()
    hemi_mass = MODEL.hemi_mass_kg
    assert s.tether_tension_n == pytest.approx(hemi_mass * 1.28**2 * 2.8, rel=1e-12)
    assert not s.tether_slack
    # The paper's max 0.47 G on a Hemi-SPLITTER at w_y = 1.28 rad/s, r_x = 2.8 m.
    assert s.hemi_acceleration_g == pytest.approx([0.468, 0.468], abs=1e-3)
    # Reeling in hard while barely spinning: the tether would have to push.
    slow = _flight(w0=(0.0, 0.05, 0.0))
    slow.command_joints(joint_positions_from_radii(MODEL, (1.0, 0.2, 0.2)))
    slack = []
    for _ in range(700):
        slow.step()
        slack.append(slow.state().tether_slack)
    assert any(slack) and not all(slack)
