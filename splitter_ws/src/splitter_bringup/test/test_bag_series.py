"""A bag read back into a RunSeries (core.bag_series, run_bag) and `splitter plot`."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest
from rclpy.serialization import serialize_message

from splitter_bag import BagWriter, WriterOptions
from splitter_bringup.analysis import bag_series
from splitter_bringup.run.run_bag import read_run_series
from splitter_model.kinematics import joint_positions_from_radii
from splitter_model.model import RobotModel
from splitter_msgs_py import conversions as cv
from splitter_msgs_py import names

STEP_NS = 5_000_000  # [ns] state rate 200 Hz
N = 200  # 1 s


def _w(t: float) -> np.ndarray:
    return np.array([0.3 * np.cos(t), 1.0 + 0.1 * t, -0.2 * t])


def _radii(t: float) -> np.ndarray:
    return np.array([1.4 + 0.2 * t, 0.2 + 0.1 * t, 0.3 - 0.05 * t])


def _quat(t: float) -> np.ndarray:
    half = 0.5 * 0.4 * t
    return np.array([np.cos(half), 0.0, np.sin(half), 0.0])


@pytest.fixture(scope="module")
def run_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    model = RobotModel()
    bag_dir = tmp_path_factory.mktemp("series") / "run"
    options = WriterOptions(custom_data={"gravity_m_s2": "1.625", "scenario": "synthetic"})
    with BagWriter(bag_dir, options) as bag:
        for topic in (*bag_series.STATE_TOPICS, names.INERTIA_SETPOINT, names.GAIT_PHASE):
            bag.add_topic(topic, names.TOPIC_TYPES[topic])
        bag.add_topic(names.JUMP_COMMAND, names.TOPIC_TYPES[names.JUMP_COMMAND])

        def put(topic: str, msg: object, t_ns: int) -> None:
            bag.write(topic, serialize_message(msg), t_ns, t_ns)

        put(names.GAIT_PHASE, cv.message_class("std_msgs/msg/String")(data="IN_FLIGHT"), 0)
        for k in range(N):
            t_ns = k * STEP_NS
            t = t_ns * 1e-9
            q = _quat(t)
            put(names.IMU, cv.imu_to_msg(t_ns, q, _w(t), [0, 0, 0]), t_ns)
            velocity = np.array([2.0 * t, 0.5, 3.0 - 1.625 * t])
            position = np.array([t * t, 0.5 * t, 3.0 * t - 0.8125 * t * t])
            put(names.ODOM, cv.odom_to_msg(t_ns, position, q, velocity, _w(t)), t_ns)
            put(names.INERTIA, cv.vector3_to_msg(t_ns, [10.0 + t, 20.0, 30.0 - t]), t_ns)
            joints = joint_positions_from_radii(model, _radii(t))
            put(names.JOINT_STATES, cv.joint_state_to_msg(t_ns, joints), t_ns)
            if k % 2 == 0 and k >= 4:  # setpoints from 20 ms on, every 10 ms
                put(names.INERTIA_SETPOINT, cv.vector3_to_msg(t_ns, [100.0 + k, 0, 0]), t_ns)
            if k % 2 == 0 and k >= 100:  # thrust from 0.5 s on
                put(
                    names.JUMP_COMMAND,
                    cv.wrench_to_msg(t_ns, [40.0, 0.0, 40.0], [0, 0, 0], "world"),
                    t_ns,
                )
            if k == 150:
                put(names.GAIT_PHASE, cv.message_class("std_msgs/msg/String")(data="LANDING"), t_ns)
        # An IMU sample no other state topic has: left out of the aligned series.
        put(names.IMU, cv.imu_to_msg(N * STEP_NS, [1, 0, 0, 0], [9, 9, 9], [0, 0, 0]), N * STEP_NS)
    return bag_dir


def test_pure_alignment_helpers() -> None:
    assert list(bag_series.common_stamps([0, 5, 10, 15], [5, 10, 20], [10, 5])) == [5, 10]
    vals = bag_series.values_at([0, 5, 5, 10], [1.0, 2.0, 3.0, 4.0], [5, 10])
    assert list(vals) == [3.0, 4.0]  # the last of duplicated stamps
    with pytest.raises(bag_series.BagSeriesError):
        bag_series.values_at([0, 10], [1.0, 2.0], [5])
    filled = bag_series.forward_fill([10, 20], [1.0, 2.0], [0, 10, 15, 20, 30])
    assert list(filled) == [1.0, 1.0, 1.0, 2.0, 2.0]
    holes = bag_series.forward_fill([10], [1.0], [0, 10], backfill=False)
    assert np.isnan(holes[0]) and holes[1] == 1.0
    assert bag_series.forward_fill_labels([10], ["A"], [0, 10, 20], before="-") == ["-", "A", "A"]


def test_bag_reads_back_into_an_aligned_run_series(run_bag: Path) -> None:
    series = read_run_series(run_bag)
    assert len(series) == N  # the stray IMU stamp is not a sample
    t = series.t_s
    assert np.allclose(np.diff(t), STEP_NS * 1e-9)
    assert series.gravity_m_s2 == 1.625  # from the bag's custom_data
    assert np.allclose(series.angular_velocity_rad_s, np.array([_w(x) for x in t]))
    assert np.allclose(series.orientation_wxyz, np.array([_quat(x) for x in t]))
    assert np.allclose(series.velocity_m_s[:, 0], 2.0 * t)
    assert np.allclose(series.principal_inertia_kg_m2[:, 0], 10.0 + t)
    # Radii through joint angles and back (limb FK): the radii the joints were made from.
    assert np.allclose(series.radii_m, np.array([_radii(x) for x in t]), atol=1e-9)
    # Setpoints: forward-filled, the first back-fills the start.
    sp = series.inertia_setpoint_kg_m2[:, 0]
    assert sp[0] == sp[4] == 104.0
    assert sp[5] == 104.0 and sp[6] == 106.0 and sp[-1] == 100.0 + (N - 2)
    assert series.gait_phase[0] == "IN_FLIGHT" and series.gait_phase[150] == "LANDING"
    assert series.gait_phase[149] == "IN_FLIGHT"
    assert series.jump_force_n is not None
    assert np.all(series.jump_force_n[:100] == 0.0)
    assert np.all(series.jump_force_n[100:] == [40.0, 0.0, 40.0])


def test_missing_state_topic_is_named(tmp_path: Path) -> None:
    bag_dir = tmp_path / "imu_only"
    with BagWriter(bag_dir) as bag:
        bag.add_topic(names.IMU, names.TOPIC_TYPES[names.IMU])
        bag.write(
            names.IMU, serialize_message(cv.imu_to_msg(0, [1, 0, 0, 0], [0] * 3, [0] * 3)), 0, 0
        )
    with pytest.raises(bag_series.BagSeriesError, match=names.ODOM):
        read_run_series(bag_dir)


def test_plot_command_writes_the_figures(run_bag: Path, tmp_path: Path, capsys) -> None:
    from splitter_bringup.cli import plot

    parser = argparse.ArgumentParser()
    plot.add_arguments(parser)
    out = tmp_path / "png"
    assert plot.main(parser.parse_args([str(run_bag), "--out", str(out)])) == 0
    for name in ("flight.png", "quaternion.png", "trajectory.png"):
        assert (out / name).stat().st_size > 10_000
    summary = json.loads(capsys.readouterr().out)
    assert summary["samples"] == N
    assert summary["peak_v_x_m_s"] == pytest.approx(2.0 * (N - 1) * STEP_NS * 1e-9)
    assert plot.main(parser.parse_args([str(tmp_path / "nothing"), "--out", str(out)])) == 1


def test_the_metrics_read_the_ground_truth_when_the_bag_has_it(tmp_path: Path) -> None:
    """A noisy, biased /splitter/imu and an estimated /splitter/inertia never enter the
    series when the bag holds /splitter/truth/imu and /splitter/truth/inertia."""
    from splitter_bringup.run.run_bag import run_check_arrays_from_bag

    model = RobotModel()
    bag_dir = tmp_path / "truth"
    topics = (*bag_series.STATE_TOPICS, names.TRUTH_IMU, names.TRUTH_INERTIA)
    bias = np.array([0.01, -0.02, 0.03])  # [rad/s]
    with BagWriter(bag_dir) as bag:
        for topic in topics:
            bag.add_topic(topic, names.TOPIC_TYPES[topic])
        for k in range(5):
            t_ns, t = k * STEP_NS, k * STEP_NS * 1e-9
            q, w = _quat(t), _w(t)
            msgs = {
                names.IMU: cv.imu_to_msg(t_ns, q, w + bias, [0, 0, 0]),
                names.TRUTH_IMU: cv.imu_to_msg(t_ns, q, w, [0, 0, 0]),
                names.ODOM: cv.odom_to_msg(t_ns, [0, 0, 0], q, [0, 0, 0], w),
                names.INERTIA: cv.vector3_to_msg(t_ns, [1.0, 2.0, 3.0]),  # an estimate
                names.TRUTH_INERTIA: cv.vector3_to_msg(t_ns, [1.5, 2.5, 3.5]),
                names.JOINT_STATES: cv.joint_state_to_msg(
                    t_ns, joint_positions_from_radii(model, _radii(t))
                ),
            }
            for topic, msg in msgs.items():
                bag.write(topic, serialize_message(msg), t_ns, t_ns)
    series = read_run_series(bag_dir)
    truth = np.array([_w(x) for x in series.t_s])
    np.testing.assert_allclose(series.angular_velocity_rad_s, truth)
    np.testing.assert_array_equal(series.principal_inertia_kg_m2[-1], [1.5, 2.5, 3.5])
    np.testing.assert_allclose(run_check_arrays_from_bag(bag_dir)["angular_velocity_rad_s"], truth)
    assert bag_series.truth_topic(names.IMU, {names.IMU}) == names.IMU  # an old bag
