"""flight_estimator node: its rate estimate carries the tick's accelerometer reading.

With robot errors the allocator reads ``/splitter/estimate/imu`` instead of the
simulator's IMU; it tells from the specific force whether the feet hold the robot
(``AllocatorConfig.supported_*``). An estimate that zeroed it left the graph's reel
coasting on the ground where the library loop's braked.
"""

from __future__ import annotations

import numpy as np

from splitter_model.kinematics import joint_positions_from_radii
from splitter_model.model import RobotModel
from splitter_mpc.flight_estimator_node import FlightEstimatorNode
from splitter_msgs_py import conversions as conv
from splitter_msgs_py import names
from splitter_msgs_py.inspection import record_publications
from splitter_msgs_py.testing import node_under_test

TICK_NS = 10_000_000  # [ns]
STANDING_M_S2 = (0.3, -0.2, 1.62)  # [m/s^2] body: the Moon's gravity held by the legs


def _send_tick(node: FlightEstimatorNode, t_ns: int, specific_force: tuple) -> None:
    radii = joint_positions_from_radii(RobotModel(), (2.8, 0.2, 0.2))
    node._on_input(  # the subscription callback, called as rclpy would
        names.IMU,
        conv.imu_to_msg(t_ns, (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.4), specific_force),
    )
    node._on_input(names.JOINT_STATES, conv.joint_state_to_msg(t_ns, radii))
    for topic in names.LEG_FORCES:
        msg = conv.wrench_to_msg(t_ns, (0.0, 0.0, 20.0), frame_id=names.BASE_FRAME)
        node._on_input(topic, msg)


def test_the_estimate_passes_the_accelerometer_on(ros_context) -> None:
    with node_under_test(FlightEstimatorNode, ros_context) as node:
        published = record_publications(node)
        for k, force in enumerate([STANDING_M_S2, STANDING_M_S2, (0.0, 0.0, 0.0)]):
            _send_tick(node, k * TICK_NS, force)
        estimates = [conv.imu_from_msg(m) for m in published[names.ESTIMATE_IMU]]
    assert [e.t_ns for e in estimates] == [0, TICK_NS, 2 * TICK_NS]
    for estimate, force in zip(estimates, [STANDING_M_S2, STANDING_M_S2, (0, 0, 0)], strict=True):
        np.testing.assert_array_equal(estimate.linear_acceleration_m_s2, force)
