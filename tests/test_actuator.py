"""Actuator sizing against the paper (each within 3 %), physics checks, and the run check."""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
import pytest

from splitter_bringup.analysis.actuator_sizing import (
    PAPER_VALUES,
    JumpAssumptions,
    knee_moment_arm_m,
    leg_length_m,
    size_actuators,
)
from splitter_bringup.analysis.run_check import check_run, limb_joint_torques_nm
from splitter_bringup.analysis.series import RunSeries
from splitter_bringup.cli import actuator as actuator_cli
from splitter_model.kinematics import joint_positions_from_radii
from splitter_model.model import RobotModel

MODEL = RobotModel()

# The list, as the paper prints it.
PAPER = {
    "takeoff_speed_m_s": 4.0,
    "takeoff_acceleration_m_s2": 21.7,
    "leg_force_n": 52.5,
    "hip_torque_nm": 10.5,
    "hip_speed_rpm": 270.3,
    "continuous_torque_nm": 12.3,
    "peak_torque_nm": 34.3,
    "output_speed_rpm": 800.0,
    "motor_mass_kg": 0.321,
    "static_payload_kg": 142.0,
    "dynamic_payload_kg": 20.0,
}


@pytest.mark.parametrize(("key", "paper"), sorted(PAPER.items()))
def test_each_paper_number_within_three_percent(key: str, paper: float) -> None:
    figure = size_actuators().figure(key)
    assert figure.paper == paper == PAPER_VALUES[key]
    assert figure.value == pytest.approx(paper, rel=0.03)
    assert figure.within_tolerance


def test_jump_obeys_kinematics_force_balance_and_energy() -> None:
    a = JumpAssumptions()
    r = size_actuators(a)
    v, s = r.figure("takeoff_speed_m_s").value, r.figure("stroke_m").value
    acc, force = r.figure("takeoff_acceleration_m_s2").value, r.figure("leg_force_n").value
    g, m = a.gravity_m_s2, a.robot_mass_kg
    # ballistic apex: 1/2 v^2 = g h
    assert 0.5 * v**2 == pytest.approx(g * a.apex_height_m)
    # the legs' work over the stroke = potential gained in the stroke + kinetic at take-off
    assert a.legs * force * s == pytest.approx(m * g * s + 0.5 * m * v**2)
    assert v**2 == pytest.approx(2.0 * acc * s)
    # geometry: the stroke is the stretch of the two-link leg, the arm its largest knee offset
    assert s == pytest.approx(2 * 0.2 * math.cos(math.radians(21.0)))
    assert knee_moment_arm_m(0.2, 0.2, math.pi) == pytest.approx(0.2)
    assert knee_moment_arm_m(0.2, 0.2, math.pi / 2) == pytest.approx(0.2 * math.sqrt(0.5))
    assert leg_length_m(0.2, 0.2, 0.0) == pytest.approx(0.4)


def test_hip_speed_from_the_leg_jacobian_matches_finite_differences() -> None:
    """Foot speed v along the hip-foot line: hip pitch speed from L(k) and q2(k) numerically."""
    a = JumpAssumptions()
    v = size_actuators(a).figure("takeoff_speed_m_s").value
    k, h = a.takeoff_knee_rad, 1e-7
    dl_dk = (leg_length_m(0.2, 0.2, k + h) - leg_length_m(0.2, 0.2, k - h)) / (2 * h)
    knee_speed = v / abs(dl_dk)
    hip_speed = knee_speed / 2.0  # equal links: q2 = -k / 2
    rpm = 60.0 / (2 * math.pi)
    assert size_actuators(a).figure("hip_speed_rpm").value == pytest.approx(hip_speed * rpm)
    assert size_actuators(a).figure("knee_speed_rpm").value == pytest.approx(knee_speed * rpm)


def test_the_inferred_assumption_matters_and_full_stroke_misses_the_paper() -> None:
    """The take-off angle is the one fitted input: other angles break the 270.3 RPM."""
    for degrees in (38.0, 47.0):
        changed = size_actuators(JumpAssumptions(takeoff_knee_rad=math.radians(degrees)))
        assert not changed.figure("hip_speed_rpm").within_tolerance
    notes = " ".join(size_actuators().notes)
    assert "20.43 m/s^2" in notes and "outside 3 %" in notes


def test_cli_json_lists_every_number_beside_the_paper(capsys) -> None:
    parser = argparse.ArgumentParser()
    actuator_cli.add_arguments(parser)
    assert actuator_cli.main(parser.parse_args(["--json"])) == 0
    out = json.loads(capsys.readouterr().out)
    by_key = {f["key"]: f for f in out["figures"]}
    for key, paper in PAPER.items():
        assert by_key[key]["paper"] == paper
        assert abs(by_key[key]["relative_error"]) <= 0.03
    assert "takeoff_knee_deg" in out["assumptions"] and out["notes"]
    # a fitted angle far off the paper's fails the command
    assert actuator_cli.main(parser.parse_args(["--takeoff-knee-deg", "60"])) == 1


# --- run check -------------------------------------------------------------------------
def _series(t: np.ndarray, q: np.ndarray, w: np.ndarray) -> RunSeries:
    n = len(t)
    return RunSeries(
        t_s=t,
        angular_velocity_rad_s=w,
        orientation_wxyz=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)),
        principal_inertia_kg_m2=np.zeros((n, 3)),
        inertia_setpoint_kg_m2=np.zeros((n, 3)),
        radii_m=np.zeros((n, 3)),
        position_m=np.zeros((n, 3)),
        velocity_m_s=np.zeros((n, 3)),
        joint_position=q,
    )


def test_spin_load_torques_match_the_centripetal_moments() -> None:
    """Radial limbs held still in a steady spin about y: tip force m w^2 r_x along -x."""
    t = np.arange(0.0, 0.5, 0.005)
    q = np.tile(joint_positions_from_radii(MODEL, [2.8, 0.2, 0.2]), (len(t), 1))
    w = np.tile([0.0, 1.3, 0.0], (len(t), 1))
    tau = limb_joint_torques_nm(MODEL, t, q, w)
    m, w2, r_x, r_y = MODEL.limb_mass_y_kg, 1.3**2, 2.8, 0.2
    knee = q[0, 2]
    hip_pitch = m * w2 * r_x * r_y  # moment of the tip force about the hip
    knee_moment = m * w2 * r_x * 0.2 * math.cos(knee / 2.0)  # about the knee (half the reach)
    for limb in (0, 1, 4, 5):  # the y limbs
        abduction, pitch, knee_tau = np.abs(tau[10, 3 * limb : 3 * limb + 3])
        assert abduction == pytest.approx(0.0, abs=1e-6)
        assert pitch == pytest.approx(hip_pitch, rel=1e-5)
        assert knee_tau == pytest.approx(knee_moment, rel=1e-5)


def test_check_reports_speed_and_flags_violations(tmp_path, capsys) -> None:
    t = np.arange(0.0, 1.5, 0.005)
    base = joint_positions_from_radii(MODEL, [2.0, 0.25, 0.25])
    q = np.tile(base, (len(t), 1))
    amplitude, omega = 0.3, 2 * math.pi * 2.0  # knee of limb 0: 3.77 rad/s, 47 rad/s^2 peak
    q[:, 2] = base[2] + amplitude * np.sin(omega * t)
    q[:, 24] = 4.0 + 0.2 * np.sin(2 * math.pi * 0.5 * t)  # tether: 0.63 m/s peak
    w = np.tile([0.0, 1.0, 0.0], (len(t), 1))
    checks = {c.key: c for c in check_run(MODEL, t, q, w)}
    assert checks["limb_joint_speed"].value == pytest.approx(amplitude * omega, rel=0.01)
    assert checks["tether_speed"].value == pytest.approx(0.2 * math.pi, rel=0.01)
    assert all(c.ok for c in checks.values())
    path = tmp_path / "run.npz"
    _series(t, q, w).save_npz(path)
    parser = argparse.ArgumentParser()
    actuator_cli.add_arguments(parser)
    assert actuator_cli.main(parser.parse_args(["--check-npz", str(path), "--json"])) == 0
    assert json.loads(capsys.readouterr().out)["ok"] is True
    # a 1 rad knee step in 10 ms: 100 rad/s, over 800 RPM
    q[:, 2] = base[2] + np.clip((t - 1.0) / 0.01, 0.0, 1.0)
    _series(t, q, w).save_npz(path)
    assert actuator_cli.main(parser.parse_args(["--check-npz", str(path), "--json"])) == 1
    result = json.loads(capsys.readouterr().out)
    speed = next(c for c in result["checks"] if c["key"] == "limb_joint_speed")
    assert not speed["ok"] and "hemi_a_y_pos_knee" in speed["where"]


def test_check_bag_reads_joint_states_imu_phase_and_thrust(tmp_path, capsys) -> None:
    from rclpy.serialization import serialize_message
    from std_msgs.msg import String

    from splitter_bag import BagWriter
    from splitter_msgs_py import conversions as conv
    from splitter_msgs_py import names

    t_ns = np.arange(0, 400) * 5_000_000
    base = joint_positions_from_radii(MODEL, [2.0, 0.25, 0.25])
    bag_dir = tmp_path / "bag"
    with BagWriter(bag_dir) as bag:
        for topic in (names.JOINT_STATES, names.IMU, names.GAIT_PHASE, names.JUMP_COMMAND):
            bag.add_topic(topic, names.TOPIC_TYPES[topic])
        bag.write(names.GAIT_PHASE, serialize_message(String(data="IN_FLIGHT")), 0, 0)
        for t in t_ns:
            q = base.copy()
            q[24] = 4.0 + 0.5 * t * 1e-9  # tether paid out at 0.5 m/s
            msgs = {
                names.JOINT_STATES: conv.joint_state_to_msg(int(t), q),
                names.IMU: conv.imu_to_msg(int(t), [1, 0, 0, 0], [0.0, 1.0, 0.0], [0, 0, 0]),
                names.JUMP_COMMAND: conv.wrench_to_msg(
                    int(t), [0.0, 0.0, 40.0 if t < 1e8 else 0.0]
                ),
            }
            for topic, msg in msgs.items():
                bag.write(topic, serialize_message(msg), int(t) + 1, int(t))
    parser = argparse.ArgumentParser()
    actuator_cli.add_arguments(parser)
    assert actuator_cli.main(parser.parse_args(["--check-bag", str(bag_dir), "--json"])) == 0
    result = json.loads(capsys.readouterr().out)
    checks = {c["key"]: c for c in result["checks"]}
    assert result["samples"] == 400
    assert checks["tether_speed"]["value"] == pytest.approx(0.5, rel=1e-6)
    assert checks["jump_joint_torque"]["value"] == pytest.approx(40.0 / 4 * 0.2)
    # 9 kg hemi at r_x = L / 2 = 2.499 m at the end, spinning at 1 rad/s, on a 2 cm spool
    r_x_end = (4.0 + 0.5 * 1.995) / 2.0
    assert checks["tether_reel_torque"]["value"] == pytest.approx(9.0 * r_x_end * 0.02, rel=1e-6)
    assert "limb_torque_flight" in checks
