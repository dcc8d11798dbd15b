"""Joint and reel faults in the simulator (``splitter_model.faults``, :mod:`.joint_faults`).

Physics: a limp joint carries no torque, so in torque-free flight with the
other joints held nothing does work on the robot: the angular momentum and the
kinetic energy about the COM are both kept while the limp limb swings (until it
meets the end of its range, an inelastic stop), the simulator's own joint
torque (``J^T F``) of the limp joint reads zero, and the actuators' work stays
zero. A locked joint and a locked reel hold under any command.
"""

from __future__ import annotations

import numpy as np
import pytest

from splitter_model.faults import FAULT_CODES, JointFault, faults_from_parameters
from splitter_model.joints import JOINT_INDEX, TETHER_INDEX
from splitter_model.kinematics import joint_positions_from_radii
from splitter_model.model import RobotModel
from splitter_sim.core.simulator import InitialState, SimConfig, Simulator

MODEL = RobotModel()
SPIN = InitialState(
    position_m=(0.0, 0.0, 10.0),
    angular_velocity_rad_s=(0.3, 0.8, 0.5),  # [rad/s] a tumble
    radii_m=(1.5, 0.25, 0.25),
)


def _flight(faults: dict[str, str], at_s: float = 0.1, compiled: bool = True) -> Simulator:
    config = SimConfig(
        ground_contact=False,
        fault_joints=tuple(faults),
        fault_kinds=tuple(faults.values()),
        fault_times_s=(at_s,) * len(faults),
    )
    return Simulator(MODEL, config, SPIN, compiled=compiled)


def _run(sim: Simulator, seconds: float) -> list:
    states = []
    for _ in range(round(seconds / sim.config.dt_s)):
        sim.step()
        states.append(sim.state())
    return states


def test_a_limp_hip_swings_without_work_momentum_and_energy_kept() -> None:
    joint = JOINT_INDEX["hemi_b_z_neg_hip_pitch"]
    sim = _flight({"hemi_b_z_neg_hip_pitch": "limp"})
    before = sim.state()
    held_torque = abs(before.joint_effort[joint])  # [N m] what the servo held
    states = _run(sim, 1.0)
    swing = max(abs(s.joint_position[joint] - before.joint_position[joint]) for s in states)
    assert swing > 1.0  # [rad] the centrifugal load swings it
    energy = np.array([s.kinetic_energy_about_com_j for s in states])
    assert np.abs(energy - before.kinetic_energy_about_com_j).max() < 1e-3 * energy[0]
    assert max(abs(s.actuator_work_j) for s in states) < 1e-3 * energy[0]
    momentum = np.array([s.angular_momentum_world for s in states])
    assert np.abs(momentum - before.angular_momentum_world).max() < 1e-8
    limp_torque = max(abs(s.joint_effort[joint]) for s in states[30:])
    assert held_torque > 0.3
    assert limp_torque < 0.05 * held_torque
    assert states[-1].joint_fault[joint] == FAULT_CODES["limp"]
    assert before.joint_fault[joint] == 0


def test_a_limp_knee_stops_at_its_range_end_and_loses_energy_there() -> None:
    joint = JOINT_INDEX["hemi_a_y_pos_knee"]
    sim = _flight({"hemi_a_y_pos_knee": "limp"})
    before = sim.state()
    states = _run(sim, 2.0)
    q = np.array([s.joint_position[joint] for s in states])
    assert q.max() <= MODEL.knee_max_rad
    assert np.isclose(q.max(), MODEL.knee_max_rad)  # it reached the stop
    lost = before.kinetic_energy_about_com_j - states[-1].kinetic_energy_about_com_j
    assert lost > 1e-3  # [J] the inelastic stop
    assert np.abs(states[-1].angular_momentum_world - before.angular_momentum_world).max() < 1e-8


def test_compiled_and_python_limp_flights_agree() -> None:
    runs = [
        _run(_flight({"hemi_b_z_neg_hip_pitch": "limp"}, compiled=c), 0.4) for c in (True, False)
    ]
    compiled, python = runs
    if not _flight({}).compiled:
        pytest.skip("no compiled kernels on this machine")
    for a, b in zip(compiled, python, strict=True):
        assert np.allclose(a.joint_position, b.joint_position, atol=1e-10)
        assert np.allclose(a.angular_velocity_rad_s, b.angular_velocity_rad_s, atol=1e-10)


@pytest.mark.parametrize("joint", ["hemi_a_z_pos_knee", "tether"])
def test_a_locked_joint_holds_where_it_failed_under_any_command(joint: str) -> None:
    sim = _flight({joint: "locked"}, at_s=0.0)
    j = JOINT_INDEX[joint]
    start = sim.state().joint_position[j]
    target = joint_positions_from_radii(MODEL, (2.0, 0.35, 0.35))
    sim.command_joints(target)
    states = _run(sim, 1.5)
    assert all(s.joint_position[j] == start for s in states)
    assert all(s.joint_velocity[j] == 0.0 for s in states)
    others = [i for i in range(len(target)) if i != j]
    assert np.allclose(states[-1].joint_position[others], target[others])
    assert states[-1].joint_fault[j] == FAULT_CODES["locked"]


def test_a_joint_locked_while_moving_stops_at_once_and_keeps_the_momentum() -> None:
    sim = _flight({})
    sim.command_joints(joint_positions_from_radii(MODEL, (2.0, 0.25, 0.25)))
    _run(sim, 0.1)
    assert sim.state().joint_velocity[TETHER_INDEX] > 0.1  # the reel is paying out
    before = sim.state().angular_momentum_world
    sim.inject_fault("tether", "locked")
    length = sim.state().joint_position[TETHER_INDEX]
    states = _run(sim, 0.5)
    assert all(s.joint_position[TETHER_INDEX] == length for s in states)
    assert np.abs(states[-1].angular_momentum_world - before).max() < 1e-8
    with pytest.raises(ValueError, match="failed already"):
        sim.inject_fault("tether", "locked")


@pytest.mark.parametrize(
    ("joints", "kinds", "times", "message"),
    [
        (("hemi_a_y_pos_knee",), ("broken",), (1.0,), "fault_kinds"),
        (("elbow",), ("locked",), (1.0,), "fault_joints"),
        (("tether",), ("limp",), (1.0,), "reel can only be 'locked'"),
        (("hemi_a_y_pos_knee",), ("locked",), (-1.0,), "fault_times_s"),
        (("hemi_a_y_pos_knee",), ("locked", "limp"), (1.0,), "same length"),
        (("hemi_a_y_pos_knee", "hemi_a_y_pos_knee"), ("locked", "limp"), (1.0, 2.0), "twice"),
    ],
)
def test_bad_fault_parameters_are_refused_naming_the_parameter(
    joints: tuple, kinds: tuple, times: tuple, message: str
) -> None:
    with pytest.raises(ValueError, match=message):
        SimConfig(fault_joints=joints, fault_kinds=kinds, fault_times_s=times)


def test_fault_parameters_round_trip() -> None:
    faults = (JointFault("tether", "locked", 1.0), JointFault("hemi_b_y_neg_knee", "limp", 0.5))
    config = SimConfig(
        fault_joints=tuple(f.joint for f in faults),
        fault_kinds=tuple(f.kind for f in faults),
        fault_times_s=tuple(f.time_s for f in faults),
    )
    assert config.faults == faults
    assert faults_from_parameters([], [], []) == ()


def test_a_limp_knee_rests_on_its_fold_stop_when_the_hip_is_pitched_to_it() -> None:
    """``splitter_model.redundancy``: in a spin across the tether the pull on a tip is
    along the tether; with the hip at the fold-stop pitch a limp knee folds onto its stop
    and stays there, where with the radial pitch it swings as a pendulum."""
    from splitter_model.redundancy import fold_stop_pitch_rad

    knee = JOINT_INDEX["hemi_a_y_pos_knee"]
    pitch = JOINT_INDEX["hemi_a_y_pos_hip_pitch"]
    spin = InitialState(
        position_m=(0.0, 0.0, 10.0),
        angular_velocity_rad_s=(0.0, 1.1, 0.0),
        radii_m=(2.8, 0.25, 0.25),
    )
    for folded in (True, False):
        config = SimConfig(
            ground_contact=False,
            fault_joints=("hemi_a_y_pos_knee",),
            fault_kinds=("limp",),
            fault_times_s=(0.0,),
        )
        sim = Simulator(MODEL, config, spin)
        command = np.array(sim.state().joint_position)
        if folded:
            command[pitch] = fold_stop_pitch_rad(MODEL)
        sim.command_joints(command)
        states = _run(sim, 4.0)
        last = np.array([s.joint_position[knee] for s in states[-200:]])  # the last second
        if folded:  # resting on the stop: the stop holds it, nothing moves, nothing works
            # (a joint pushed past its stop every step and clipped back pumped 0.7 mJ/s)
            assert np.all(last == MODEL.knee_max_rad)
            energy = [s.kinetic_energy_about_com_j for s in states[-200:]]
            assert max(energy) - min(energy) < 1e-9 * energy[0]
        else:
            assert last.max() - last.min() > 0.1  # [rad] still swinging


def test_the_scene_draws_a_failed_limb_and_a_locked_reel_red() -> None:
    from splitter_sim.core.scene import FAULT_COLOR, scene_of_state
    from splitter_sim.messages import FAULT_NS, scene_markers

    sim = _flight({"hemi_b_z_neg_knee": "locked", "tether": "locked"}, at_s=0.0)
    healthy = scene_of_state(sim.state())
    assert healthy.faulty_limbs == frozenset() and not healthy.reel_locked
    assert all(m.ns != FAULT_NS for m in scene_markers(healthy).markers)
    sim.step()
    scene = scene_of_state(sim.state())
    limb = JOINT_INDEX["hemi_b_z_neg_knee"] // 3
    assert scene.faulty_limbs == {limb} and scene.reel_locked
    (red,) = [m for m in scene_markers(scene).markers if m.ns == FAULT_NS]
    assert (red.color.r, red.color.g, red.color.b, red.color.a) == pytest.approx(FAULT_COLOR)
    points = np.array([[p.x, p.y, p.z] for p in red.points])
    np.testing.assert_allclose(points[:2], scene.limb_segments_m[limb])
    np.testing.assert_allclose(points[2:], scene.tether_m)
