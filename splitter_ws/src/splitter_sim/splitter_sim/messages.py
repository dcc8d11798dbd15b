"""The simulator's state and scene as ROS messages (and the scene's masses back).

* :func:`state_messages`: a :class:`~splitter_sim.core.simulator.SimState` as the
  messages of one step, per topic, in publishing order: what the robot's sensors
  report (``/splitter/imu`` with the gyro's errors) and the ground truth
  (``/splitter/truth/...``).
* :func:`scene_markers`: ``/splitter/markers`` (``visualization_msgs/MarkerArray``,
  world frame): 10 mass spheres (ns ``splitter_masses``, id = mass index), the
  tether (``splitter_tether``) and limb lines (``splitter_limbs``), and the scene's
  arrows (``splitter_arrows``: body axes, angular momentum, contact forces) and,
  unless level, the ground (``splitter_ground``: id 0 the base plane, a thin slab
  about the robot tilted with the slope; id ``1 + i`` step ``i``'s box;
  :func:`splitter_sim.core.scene.ground_boxes`).
* :func:`masses_to_msg` / :func:`masses_from_msg`: ``/splitter/scene/masses``
  (``geometry_msgs/PoseArray``, world frame): the ten lumped masses in index
  order, each oriented as the base frame. With the odometry, the true inertia and
  rate (``/splitter/truth/...``) and the contact wrenches it gives the whole scene
  (:func:`splitter_sim.core.scene.scene_from_pose`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from geometry_msgs.msg import Point, Pose, PoseArray
from numpy.typing import NDArray
from visualization_msgs.msg import Marker, MarkerArray

from splitter_model.rotations import quaternion_to_matrix
from splitter_model.sensors import (
    RANGE_FIELD_OF_VIEW_RAD,
    RANGE_MAX_M,
    RANGE_MIN_M,
    downward_range_m,
)
from splitter_msgs_py import conversions as cv
from splitter_msgs_py import names
from splitter_msgs_py.core.stamps import MessageValidationError
from splitter_sim.core.scene import (
    BODY_INDICES,
    FAULT_COLOR,
    N_MASSES,
    Box,
    Scene,
    ground_boxes,
)
from splitter_sim.core.simulator import SimState
from splitter_sim.core.tick import SensorReadings

MASS_NS = "splitter_masses"
BODY_SIZE_M = 0.25  # [m] sphere diameter of a hemi body
TIP_SIZE_M = 0.15  # [m] sphere diameter of a limb tip
HEMI_RGBA = ((0.9, 0.4, 0.1, 1.0), (0.1, 0.5, 0.9, 1.0))  # hemi a, hemi b
TETHER_WIDTH_M = 0.02  # [m] line width
LIMB_WIDTH_M = 0.03  # [m] line width
ARROW_SCALE_M = (0.03, 0.06, 0.1)  # [m] shaft, head width, head length
GROUND_NS = "splitter_ground"  # id 0: the base plane, 1 + i: step i
FAULT_NS = "splitter_faults"  # the limbs with a failed joint and a locked reel, red


def _point(p: Sequence[float]) -> Point:
    return Point(x=float(p[0]), y=float(p[1]), z=float(p[2]))


def _marker(stamp: object, ns: str, marker_id: int, kind: int) -> Marker:
    m = Marker()
    m.header.stamp = stamp
    m.header.frame_id = names.WORLD_FRAME
    m.ns = ns
    m.id = marker_id
    m.type = kind
    m.action = Marker.ADD
    m.pose.orientation.w = 1.0
    return m


def scene_markers(scene: Scene) -> MarkerArray:
    """The markers of ``scene``, stamped with its time (module docstring)."""
    stamp = cv.stamp_to_msg(scene.t_ns)
    out = MarkerArray()
    for i, p in enumerate(scene.mass_positions_m):
        m = _marker(stamp, MASS_NS, i, Marker.SPHERE)
        m.pose.position = _point(p)
        m.scale.x = m.scale.y = m.scale.z = BODY_SIZE_M if i in BODY_INDICES else TIP_SIZE_M
        m.color.r, m.color.g, m.color.b, m.color.a = HEMI_RGBA[i >= N_MASSES // 2]
        out.markers.append(m)
    tether = _marker(stamp, "splitter_tether", 0, Marker.LINE_STRIP)
    tether.scale.x = TETHER_WIDTH_M
    tether.color.r = tether.color.g = tether.color.b = 0.8
    tether.color.a = 1.0
    tether.points = [_point(p) for p in scene.tether_m]
    out.markers.append(tether)
    limbs = _marker(stamp, "splitter_limbs", 0, Marker.LINE_LIST)
    limbs.scale.x = LIMB_WIDTH_M
    limbs.color.r, limbs.color.g, limbs.color.b, limbs.color.a = 0.3, 0.3, 0.3, 1.0
    limbs.points = [_point(p) for segment in scene.limb_segments_m for p in segment]
    out.markers.append(limbs)
    if scene.faulty_limbs or scene.reel_locked:  # drawn over the limbs and the tether, red
        faults = _marker(stamp, FAULT_NS, 0, Marker.LINE_LIST)
        faults.scale.x = 2.0 * LIMB_WIDTH_M
        faults.color.r, faults.color.g, faults.color.b, faults.color.a = FAULT_COLOR
        segments = [scene.limb_segments_m[i] for i in sorted(scene.faulty_limbs)]
        if scene.reel_locked:
            segments.append(scene.tether_m)
        faults.points = [_point(p) for segment in segments for p in segment]
        out.markers.append(faults)
    for i, arrow in enumerate(scene.arrows):
        m = _marker(stamp, "splitter_arrows", i, Marker.ARROW)
        m.text = arrow.name
        m.points = [_point(arrow.start), _point(arrow.end)]
        m.scale.x, m.scale.y, m.scale.z = ARROW_SCALE_M
        m.color.r, m.color.g, m.color.b, m.color.a = arrow.color
        out.markers.append(m)
    if scene.ground is not None:
        for i, box in enumerate(ground_boxes(scene.ground, scene.position_m)):
            out.markers.append(box_marker(stamp, GROUND_NS, i, box))
    return out


def box_marker(stamp: object, ns: str, marker_id: int, box: Box) -> Marker:
    """A ``Marker.CUBE`` of ``box`` (world frame)."""
    m = _marker(stamp, ns, marker_id, Marker.CUBE)
    m.text = box.name
    m.pose.position = _point(box.centre_m)
    o = m.pose.orientation
    o.w, o.x, o.y, o.z = (float(v) for v in box.orientation_wxyz)
    m.scale.x, m.scale.y, m.scale.z = (float(v) for v in box.size_m)
    m.color.r, m.color.g, m.color.b, m.color.a = box.color
    return m


def masses_to_msg(scene: Scene) -> PoseArray:
    """``/splitter/scene/masses``: the lumped masses of ``scene`` (world frame)."""
    msg = PoseArray()
    msg.header.stamp = cv.stamp_to_msg(scene.t_ns)
    msg.header.frame_id = names.WORLD_FRAME
    w, x, y, z = (float(v) for v in scene.orientation_wxyz)
    for p in scene.mass_positions_m:
        pose = Pose()
        pose.position = _point(p)
        pose.orientation.w, pose.orientation.x = w, x
        pose.orientation.y, pose.orientation.z = y, z
        msg.poses.append(pose)
    return msg


def masses_from_msg(msg: PoseArray) -> NDArray[np.float64]:
    """(10, 3) mass positions of a ``/splitter/scene/masses`` message [m]."""
    if msg.header.frame_id != names.WORLD_FRAME:
        raise MessageValidationError(
            f"header.frame_id: expected '{names.WORLD_FRAME}', got {msg.header.frame_id!r}"
        )
    if len(msg.poses) != N_MASSES:
        raise MessageValidationError(f"poses: expected {N_MASSES}, got {len(msg.poses)}")
    positions = np.array([[p.position.x, p.position.y, p.position.z] for p in msg.poses])
    if not np.all(np.isfinite(positions)):
        raise MessageValidationError("poses: non-finite position")
    return positions


def state_messages(
    state: SimState, readings: SensorReadings | None = None
) -> list[tuple[str, object]]:
    """(topic, message) of every state stream of one step, stamped ``state.t_ns``.

    What the robot's sensors read (``readings``; default: the truth, exactly):
    ``/splitter/joint_states`` carries the encoders (exact) and the effort sensors;
    ``/splitter/imu`` the rate gyro (its noise variance on the diagonal of
    ``angular_velocity_covariance``); ``/splitter/hemi_*/range`` the rangefinders and
    ``/splitter/hemi_*/leg_force`` the legs' load cells. The ground truth goes on
    ``/splitter/truth/imu`` (exact rate and attitude), ``/splitter/truth/inertia``
    (exact principal moments), ``/splitter/odom`` and the contact wrenches; the IMU
    is the step's last message.
    """
    t, q, w = state.t_ns, state.orientation_wxyz, state.angular_velocity_rad_s
    gyro = w if readings is None else readings.gyro_rad_s
    gyro_noise = 0.0 if readings is None else readings.gyro_noise_rad_s
    effort = state.joint_effort if readings is None else readings.joint_effort
    if readings is None:
        rot = quaternion_to_matrix(q)
        ranges = [downward_range_m(state.mass_positions_world_m[b, 2], rot) for b in BODY_INDICES]
        leg_forces = state.leg_force_n @ rot
    else:
        ranges, leg_forces = readings.ranges_m, readings.leg_forces_n
    inertia = cv.vector3_to_msg(t, state.principal_inertia_kg_m2, names.BASE_FRAME)
    acceleration = state.linear_acceleration_m_s2
    if readings is None:
        accelerometer, accelerometer_noise = acceleration, 0.0
    else:
        accelerometer = readings.specific_force_m_s2
        accelerometer_noise = readings.accelerometer_noise_m_s2
    return [
        (names.CLOCK, cv.clock_to_msg(t)),
        (
            names.JOINT_STATES,
            cv.joint_state_to_msg(
                t,
                state.joint_position,
                state.joint_velocity,
                effort,
            ),
        ),
        *(
            (
                topic,
                cv.range_to_msg(
                    t,
                    value,
                    frame,
                    min_range_m=RANGE_MIN_M,
                    max_range_m=RANGE_MAX_M,
                    field_of_view_rad=RANGE_FIELD_OF_VIEW_RAD,
                ),
            )
            for topic, value, frame in zip(names.RANGES, ranges, names.HEMI_FRAMES, strict=True)
        ),
        *(
            (topic, cv.wrench_to_msg(t, force, (0.0, 0.0, 0.0), names.BASE_FRAME))
            for topic, force in zip(names.LEG_FORCES, leg_forces, strict=True)
        ),
        (names.INERTIA, inertia),
        (names.ODOM, cv.odom_to_msg(t, state.position_m, q, state.velocity_m_s, w)),
        *(
            (topic, cv.wrench_to_msg(t, force, torque, names.WORLD_FRAME))
            for topic, force, torque in zip(
                names.CONTACT_WRENCHES, state.contact_force_n, state.contact_torque_n_m, strict=True
            )
        ),
        (names.TRUTH_INERTIA, inertia),
        (names.TRUTH_IMU, cv.imu_to_msg(t, q, w, acceleration)),
        (
            names.IMU,
            cv.imu_to_msg(
                t,
                q,
                gyro,
                accelerometer,
                angular_velocity_variance=gyro_noise**2,
                linear_acceleration_variance=accelerometer_noise**2,
            ),
        ),
    ]
