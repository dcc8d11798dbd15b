"""The 3D scene and the flight animation (issue 19).

* Scene geometry: symmetric radii put the masses where DESIGN.md section 3 says;
  the angular momentum arrow is ``R diag(I) w``; contact arrows start at the
  hemi's lowest mass.
* Frames: ``floor(D fps) + 1`` frames for a run of duration ``D``, each showing the
  latest sample at or before its time.
* ``splitter animate BAG --out FILE``: the mp4 and the gif have as many frames as
  the bag's duration asks for, and play for ``frames / fps`` seconds.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np
import pytest
from rclpy.serialization import serialize_message

from splitter_bag import BagWriter
from splitter_bringup.analysis import bag_series
from splitter_bringup.analysis.flight_frames import caption, frame_times, sample_indices
from splitter_model.kinematics import joint_positions_from_radii
from splitter_model.model import RobotModel
from splitter_msgs_py import conversions as cv
from splitter_msgs_py import names
from splitter_sim.core.scene import (
    MOMENTUM_SCALE_M,
    Ground,
    SceneGeometry,
    contact_arrows,
    rotation_matrix,
    scene_arrows,
    scene_from_pose,
)

STEP_NS = 5_000_000  # [ns] 200 Hz
DURATION_S = 1.2  # [s] of the synthetic bag
FPS = 10.0  # [1/s]
SIZE = ("160", "120")  # [px] small: the test is about frames, not pictures


def test_symmetric_radii_place_the_masses_as_the_design_says() -> None:
    model = RobotModel()
    rx, ry, rz = 1.4, 0.25, 0.3
    body = SceneGeometry(model).body_positions(joint_positions_from_radii(model, [rx, ry, rz]))
    expected = []
    for s in (1.0, -1.0):
        expected += [[s * rx, 0, 0], [s * rx, ry, 0], [s * rx, -ry, 0]]
        expected += [[s * rx, 0, rz], [s * rx, 0, -rz]]
    np.testing.assert_allclose(body, expected, atol=1e-9)


def test_scene_arrows() -> None:
    q = np.array([math.cos(0.3), 0.0, 0.0, math.sin(0.3)])  # 0.6 rad about z
    inertia, w = np.array([10.0, 100.0, 110.0]), np.array([0.1, 1.0, -0.2])
    arrows = {a.name: a for a in scene_arrows([1.0, 2.0, 3.0], q, inertia, w)}
    assert set(arrows) == {"axis_x", "axis_y", "axis_z", "angular_momentum"}
    h = rotation_matrix(q) @ (inertia * w)
    np.testing.assert_allclose(
        arrows["angular_momentum"].end - [1.0, 2.0, 3.0], MOMENTUM_SCALE_M * h
    )
    np.testing.assert_allclose(
        arrows["axis_x"].end - arrows["axis_x"].start, 0.6 * rotation_matrix(q)[:, 0]
    )
    masses = np.zeros((10, 3))
    masses[:, 2] = np.arange(10.0)
    contact = contact_arrows(masses, [[0.0, 0.0, 0.0], [5.0, 0.0, 50.0]])
    assert [a.name for a in contact] == ["contact_b"]  # hemi a carries no force
    np.testing.assert_allclose(contact[0].start, masses[5])  # hemi b's lowest mass


def test_a_scene_holds_what_the_views_draw() -> None:
    """The typed scene: its arrows are scene_arrows', its tether and limbs join its masses."""
    q = np.array([math.cos(0.3), 0.0, 0.0, math.sin(0.3)])
    inertia, w = np.array([10.0, 100.0, 110.0]), np.array([0.1, 1.0, -0.2])
    masses = np.arange(30.0).reshape(10, 3)
    forces = [[0.0, 0.0, 0.0], [5.0, 0.0, 50.0]]
    scene = scene_from_pose(
        7,
        [1.0, 2.0, 3.0],
        q,
        mass_positions_world=masses,
        principal_inertia_kg_m2=inertia,
        angular_velocity_rad_s=w,
        contact_forces_n=forces,
        ground=Ground(),
    )
    expected = scene_arrows(
        [1.0, 2.0, 3.0], q, inertia, w, mass_positions_world=masses, contact_forces_n=forces
    )
    assert [a.name for a in scene.arrows] == [a.name for a in expected]
    for got, want in zip(scene.arrows, expected, strict=True):
        np.testing.assert_allclose([got.start, got.end], [want.start, want.end])
    np.testing.assert_array_equal(scene.tether_m, masses[[0, 5]])
    np.testing.assert_array_equal(scene.limb_segments_m[4], masses[[5, 6]])
    np.testing.assert_array_equal(scene.contact_points_m, masses[[0, 5]])  # lowest of each hemi
    assert scene.ground.height_at(3.0, -1.0) == 0.0 and scene.t_ns == 7


def test_frame_times_and_samples() -> None:
    t = np.arange(0.0, 1.0 + 1e-9, 0.005)
    times = frame_times(t, 10.0)
    assert len(times) == 11 and times[-1] == pytest.approx(1.0)
    assert len(frame_times(t[:-1], 10.0)) == 10  # 0.995 s: the frame at 1.0 s is past the end
    idx = sample_indices(t, times)
    np.testing.assert_array_equal(idx, np.arange(0, 201, 20))
    with pytest.raises(ValueError, match="fps"):
        frame_times(t, 0.0)
    assert caption(1.234, "IN_FLIGHT", 1.5) == "t =  1.23 s   IN_FLIGHT   |w| = 1.500 rad/s"


@pytest.fixture(scope="module")
def flight_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tumbling, morphing flight of DURATION_S with contact forces on hemi b."""
    model = RobotModel()
    bag_dir = tmp_path_factory.mktemp("animation") / "bag"
    with BagWriter(bag_dir) as bag:
        topics = (*bag_series.STATE_TOPICS, names.GAIT_PHASE, *names.CONTACT_WRENCHES)
        for topic in topics:
            bag.add_topic(topic, names.TOPIC_TYPES[topic])

        def put(topic: str, msg: object, t_ns: int) -> None:
            bag.write(topic, serialize_message(msg), t_ns, t_ns)

        put(names.GAIT_PHASE, cv.message_class("std_msgs/msg/String")(data="IN_FLIGHT"), 0)
        for k in range(round(DURATION_S * 1e9 / STEP_NS) + 1):
            t_ns = k * STEP_NS
            t = t_ns * 1e-9
            q = np.array([math.cos(0.5 * t), 0.0, math.sin(0.5 * t), 0.0])
            w = np.array([0.0, 1.0, 0.0])
            put(names.IMU, cv.imu_to_msg(t_ns, q, w, [0, 0, 0]), t_ns)
            put(names.ODOM, cv.odom_to_msg(t_ns, [t, 0.0, 3.0], q, [1.0, 0, 0], w), t_ns)
            put(names.INERTIA, cv.vector3_to_msg(t_ns, [1.0, 140.0, 140.0]), t_ns)
            radii = [2.8 - 0.5 * t, 0.2 + 0.1 * t, 0.2]
            put(
                names.JOINT_STATES,
                cv.joint_state_to_msg(t_ns, joint_positions_from_radii(model, radii)),
                t_ns,
            )
            for i, topic in enumerate(names.CONTACT_WRENCHES):
                put(topic, cv.wrench_to_msg(t_ns, [0.0, 0.0, 30.0 * i]), t_ns)
    return bag_dir


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_animate_frames_and_duration_match_the_bag(
    flight_bag: Path, tmp_path: Path, suffix: str, capsys
) -> None:
    import imageio.v3 as iio
    import imageio_ffmpeg

    from splitter_bringup.cli import animate

    out = tmp_path / f"flight{suffix}"
    parser = argparse.ArgumentParser()
    animate.add_arguments(parser)
    args = parser.parse_args(
        [
            str(flight_bag),
            "--out",
            str(out),
            "--fps",
            str(FPS),
            "--width",
            SIZE[0],
            "--height",
            SIZE[1],
        ]
    )
    assert animate.main(args) == 0
    report = json.loads(capsys.readouterr().out)
    expected_frames = math.floor(DURATION_S * FPS + 1e-9) + 1  # 13: t = 0, 0.1, ..., 1.2 s
    assert report["bag_duration_s"] == pytest.approx(DURATION_S)
    assert report["frames"] == expected_frames
    assert report["duration_s"] == pytest.approx(expected_frames / FPS)
    if suffix == ".mp4":
        frames, seconds = imageio_ffmpeg.count_frames_and_secs(str(out))
        assert frames == expected_frames
        assert seconds == pytest.approx(expected_frames / FPS, abs=0.5 / FPS)
    else:
        images = iio.imread(out, index=None)
        assert images.shape[0] == expected_frames
        assert images.shape[1:3] == (int(SIZE[1]), int(SIZE[0]))
        durations_ms = [iio.immeta(out, index=i)["duration"] for i in range(expected_frames)]
        assert sum(durations_ms) == pytest.approx(1000.0 * expected_frames / FPS)


def test_animate_rejects_other_formats(flight_bag: Path, tmp_path: Path) -> None:
    from splitter_bringup.cli import animate

    parser = argparse.ArgumentParser()
    animate.add_arguments(parser)
    assert animate.main(parser.parse_args([str(flight_bag), "--out", str(tmp_path / "x.avi")])) == 2
