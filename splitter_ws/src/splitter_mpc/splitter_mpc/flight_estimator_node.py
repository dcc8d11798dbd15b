"""``flight_estimator``: body rate, gyro bias and masses from what the robot measures.

ROS plumbing over :class:`splitter_mpc.core.estimator_tick.EstimatorTick` (the
library loop drives the same object). Lockstep: once it holds ``/splitter/imu``
(the rate gyro, with the robot's bias and noise), ``/splitter/joint_states`` (the
encoders and the joint efforts) and both ``/splitter/hemi_*/leg_force`` (on the
ground the flight model does not hold) stamped with the same control tick ``t``, it
publishes, stamped ``t`` and in this order:

* ``/splitter/estimate/masses`` (geometry_msgs/Vector3Stamped: m_x, m_y, m_z [kg]),
* ``/splitter/estimate/gyro_bias`` (geometry_msgs/Vector3Stamped [rad/s], base),
* ``/splitter/estimate/hemi_inertia`` (geometry_msgs/Vector3Stamped: each hemi body's
  own principal moments [kg m^2], base; zero unless ``hemi_inertia_prior_kg_m2``),
* ``/splitter/estimate/inertia`` (geometry_msgs/Vector3Stamped: the estimated
  robot's principal moments at the encoders' radii [kg m^2], base),
* ``/splitter/estimate/imu`` (sensor_msgs/Imu: the estimated rate with its
  covariance, the integrated attitude),

and ``/diagnostics`` every ``diagnostics_period_s`` of simulated time (the
estimates with their standard deviations). With robot errors in the scenario the
MPC and the allocator are remapped onto these topics (``/splitter/imu`` ->
``/splitter/estimate/imu``, ``/splitter/inertia`` -> ``/splitter/estimate/inertia``)
and the MPC plans with the estimated masses. Bad messages are rejected with a
throttled warning; the tick then uses the last good one of that topic.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped, WrenchStamped
from rclpy.node import Node
from sensor_msgs.msg import Imu, JointState

from splitter_model.model import RobotModel
from splitter_mpc.core.estimator import EstimatorConfig, FlightEstimate
from splitter_mpc.core.estimator_tick import EstimatorTick, GyroSample, JointReading
from splitter_mpc.core.gait_tick import MAX_LEG_FORCE_N
from splitter_msgs_py import names
from splitter_msgs_py.conversions import (
    MessageValidationError,
    imu_from_msg,
    imu_to_msg,
    joint_state_from_msg,
    vector3_to_msg,
    wrench_from_msg,
)
from splitter_msgs_py.core.parameter_fields import PERIOD_S, parameter_field
from splitter_msgs_py.node_pattern import admitted_stamp, default_sim_time, run_node
from splitter_msgs_py.node_status import publish_status
from splitter_msgs_py.parameters import (
    InvalidParameterError,
    config_from_values,
    declare_parameters,
    specs_from_config,
    warn_throttled,
)
from splitter_msgs_py.qos import qos_for

NODE_NAME = "flight_estimator"
NS_PER_S = 1_000_000_000


@dataclass(frozen=True)
class EstimatorNodeSettings:
    """The node's settings besides the estimator's noise model."""

    control_period_s: float = parameter_field(
        0.01, "the control tick the estimates are published on [s]", bounds=PERIOD_S
    )
    diagnostics_period_s: float = parameter_field(
        0.1, "diagnostics period, simulated time [s]", bounds=PERIOD_S
    )


PARAMETERS = (*specs_from_config(EstimatorConfig), *specs_from_config(EstimatorNodeSettings))


def _read_gyro(msg: Imu) -> GyroSample:
    if msg.header.frame_id != names.BASE_FRAME:
        raise MessageValidationError(
            f"header.frame_id: expected {names.BASE_FRAME!r}, got {msg.header.frame_id!r}"
        )
    sample = imu_from_msg(msg)
    return GyroSample(
        sample.angular_velocity_rad_s, sample.orientation_wxyz, sample.linear_acceleration_m_s2
    )


def _read_joints(msg: JointState) -> JointReading:
    sample = joint_state_from_msg(msg)
    return JointReading(sample.position, sample.velocity, sample.effort)


def _read_leg_force(msg: WrenchStamped) -> np.ndarray:
    sample = wrench_from_msg(msg)
    if sample.frame_id != names.BASE_FRAME:
        raise MessageValidationError(
            f"header.frame_id: expected {names.BASE_FRAME!r}, got {sample.frame_id!r}"
        )
    if float(np.abs(sample.force_n).max()) > MAX_LEG_FORCE_N:
        raise MessageValidationError(
            f"wrench.force: {sample.force_n.tolist()} beyond +-{MAX_LEG_FORCE_N:g} N"
        )
    return sample.force_n


READERS = {
    names.IMU: (Imu, _read_gyro),
    names.JOINT_STATES: (JointState, _read_joints),
    names.LEG_FORCE_A: (WrenchStamped, _read_leg_force),
    names.LEG_FORCE_B: (WrenchStamped, _read_leg_force),
}


def estimate_values(estimate: FlightEstimate) -> dict[str, float]:
    """The estimate as diagnostics values (with the standard deviations)."""
    values: dict[str, float] = {}
    for axis, b, s in zip("xyz", estimate.gyro_bias_rad_s, estimate.bias_std_rad_s, strict=True):
        values[f"gyro_bias_{axis}_rad_s"] = float(b)
        values[f"gyro_bias_{axis}_std_rad_s"] = float(s)
    for axis, m in zip("xyz", estimate.masses_kg, strict=True):
        values[f"mass_{axis}_kg"] = float(m)
    values["mass_ratio_y_x"] = float(estimate.mass_ratios[0])
    values["mass_ratio_z_x"] = float(estimate.mass_ratios[1])
    values["effort_updates"] = float(estimate.effort_updates)  # ticks whose efforts weighed
    return values


class FlightEstimatorNode(Node):
    """Answers each control tick's gyro + encoders with the flight estimate."""

    def __init__(self, **kwargs) -> None:
        super().__init__(NODE_NAME, **default_sim_time(kwargs))
        try:
            values = declare_parameters(self, PARAMETERS)
            try:
                config = config_from_values(EstimatorConfig, values)
                settings = config_from_values(EstimatorNodeSettings, values)
            except ValueError as exc:
                raise InvalidParameterError(f"parameters: {exc}") from exc
        except InvalidParameterError:
            self.destroy_node()
            raise
        self.settings = settings
        self.tick = EstimatorTick(RobotModel(), config, round(settings.control_period_s * NS_PER_S))
        self._diagnostics_ns = round(settings.diagnostics_period_s * NS_PER_S)
        self._estimate_pubs = {
            topic: self.create_publisher(msg_type, topic, qos_for(topic))
            for topic, msg_type in (
                (names.ESTIMATE_MASSES, Vector3Stamped),
                (names.ESTIMATE_GYRO_BIAS, Vector3Stamped),
                (names.ESTIMATE_HEMI_INERTIA, Vector3Stamped),
                (names.ESTIMATE_INERTIA, Vector3Stamped),
                (names.ESTIMATE_IMU, Imu),
            )
        }
        self._diagnostics_pub = self.create_publisher(
            DiagnosticArray, names.DIAGNOSTICS, qos_for(names.DIAGNOSTICS)
        )
        for topic, (msg_type, _read) in READERS.items():
            self.create_subscription(
                msg_type, topic, lambda msg, topic=topic: self._on_input(topic, msg), qos_for(topic)
            )
        self.get_logger().info("ready")

    def _on_input(self, topic: str, msg: object) -> None:
        t_ns = admitted_stamp(
            self,
            self.tick.stamps,
            topic,
            msg,
            consequence="dropped, keeping the last good message",
        )
        if t_ns is None:
            return
        try:
            value = READERS[topic][1](msg)
        except MessageValidationError as exc:
            warn_throttled(self, topic, f"rejected {topic}: {exc}; using the last good one")
            value = None
        estimate = self.tick.add(topic, t_ns, value)
        if estimate is not None:
            self._publish(estimate)

    def _publish(self, e: FlightEstimate) -> None:
        t = e.t_ns
        pub = self._estimate_pubs
        pub[names.ESTIMATE_MASSES].publish(vector3_to_msg(t, e.masses_kg, names.BASE_FRAME))
        pub[names.ESTIMATE_GYRO_BIAS].publish(
            vector3_to_msg(t, e.gyro_bias_rad_s, names.BASE_FRAME)
        )
        pub[names.ESTIMATE_HEMI_INERTIA].publish(
            vector3_to_msg(t, e.hemi_inertia_kg_m2, names.BASE_FRAME)
        )
        pub[names.ESTIMATE_INERTIA].publish(
            vector3_to_msg(t, e.principal_inertia_kg_m2, names.BASE_FRAME)
        )
        # the accelerometer passes through: the allocator reads support from it
        imu = imu_to_msg(
            t, e.orientation_wxyz, e.angular_velocity_rad_s, self.tick.specific_force_m_s2
        )
        imu.angular_velocity_covariance = [float(v) for v in e.covariance[0:3, 0:3].ravel()]
        pub[names.ESTIMATE_IMU].publish(imu)
        if t % self._diagnostics_ns == 0:
            publish_status(
                self,
                self._diagnostics_pub,
                t,
                f"{NODE_NAME}: estimate",
                (0, "estimating", estimate_values(e)),
            )


def main(args: list[str] | None = None) -> int:
    """Run the node until Ctrl-C or shutdown; an invalid parameter stops it with exit code 1."""
    return run_node(lambda stop: FlightEstimatorNode(), NODE_NAME, args)


if __name__ == "__main__":
    raise SystemExit(main())
