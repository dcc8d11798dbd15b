"""The flight estimator's control tick, ROS-free: the gyro and the encoders joined, estimated.

The ``flight_estimator`` node converts messages into :meth:`EstimatorTick.add` and
publishes what it answers; the library closed loop calls :meth:`EstimatorTick.on_sensors`
with the same values, in the same order, so both estimate the same numbers.

* Inputs of tick ``t`` (a multiple of the control period): the rate gyro (the
  ``/splitter/imu`` message: its angular velocity; the orientation of the first one
  is the attitude the robot knows at release, from then on integrated) and the joint
  sensors (``/splitter/joint_states``: positions, turned into the radii with the
  nominal model's kinematics; velocities and efforts, which weigh the masses) and the
  legs' load cells (``/splitter/hemi_*/leg_force``: on the ground the flight model does
  not hold, so bias and masses are held and the rate follows the gyro).
  Joined by a
  :class:`~splitter_mpc.core.tick_inputs.TickAssembler`.
* The answer of tick ``t``: the :class:`~splitter_mpc.core.estimator.FlightEstimate`
  stamped ``t``: rate, attitude, inertia, masses, gyro bias and their covariance.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.kinematics import radii_from_joint_positions
from splitter_model.model import RobotModel
from splitter_mpc.core.estimator import (
    EstimatorConfig,
    FlightEstimate,
    FlightEstimator,
    JointReading,
)
from splitter_mpc.core.tick_inputs import TickAssembler
from splitter_msgs_py import names
from splitter_msgs_py.core.stamps import StampGate

TICK_INPUTS = (names.IMU, names.JOINT_STATES, *names.LEG_FORCES)


@dataclass(frozen=True)
class GyroSample:
    """What the estimator takes from an IMU message."""

    angular_velocity_rad_s: NDArray[np.float64]  # (3,) body [rad/s], biased and noisy
    orientation_wxyz: NDArray[np.float64]  # (4,) used once: the attitude at release
    # (3,) body [m/s^2]: the accelerometer (what pushes the centre of mass besides gravity)
    specific_force_m_s2: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))


class EstimatorTick:
    """Joins each control tick's gyro and encoder readings and runs the flight estimator."""

    def __init__(
        self,
        model: RobotModel,
        config: EstimatorConfig | None = None,
        control_period_ns: int = 10_000_000,
    ) -> None:
        self.model = model
        self.estimator = FlightEstimator(model, config)
        self.ticks = TickAssembler(int(control_period_ns), TICK_INPUTS)
        self.stamps = StampGate()  # the node's stamp rules per topic
        self.last: FlightEstimate | None = None
        # [m/s^2] body, the accelerometer of the last tick estimated: passed on with the
        # estimate (the allocator tells from it whether the feet hold the robot)
        self.specific_force_m_s2: NDArray[np.float64] = np.zeros(3)

    def add(self, topic: str, t_ns: int, value: object | None) -> FlightEstimate | None:
        """A gyro sample or a joint reading (None: rejected) stamped ``t_ns``.

        Returns the estimate of the tick it completes, else None.
        """
        if topic not in TICK_INPUTS:
            raise ValueError(f"not an input of the flight estimator: {topic}")
        events = self.ticks.add(topic, int(t_ns), value)
        if events.completed is None:
            return None
        t, inputs = events.completed
        samples = self.ticks.samples(inputs)
        gyro, joints = samples[names.IMU], samples[names.JOINT_STATES]
        legs = [samples[topic] for topic in names.LEG_FORCES]
        if gyro is None or joints is None or any(f is None for f in legs):  # nothing good yet
            return None
        return self.on_sensors(t, gyro, joints, legs)  # type: ignore[arg-type]

    def on_sensors(
        self,
        t_ns: int,
        gyro: GyroSample,
        joints: JointReading,
        leg_forces_n: ArrayLike | None = None,
    ) -> FlightEstimate:
        """Tick ``t_ns`` from plain values: the estimate after this gyro, joint reading and
        leg load cells ((2, 3) [N]; a hemi whose legs push harder than the estimator's
        ``stance_force_threshold_n`` is on the ground: no flight model then)."""
        radii = radii_from_joint_positions(self.model, joints.position)
        in_flight = leg_forces_n is None or bool(
            np.all(
                np.linalg.norm(np.asarray(leg_forces_n, dtype=float).reshape(2, 3), axis=1)
                <= self.estimator.config.stance_force_threshold_n
            )
        )
        self.specific_force_m_s2 = np.array(gyro.specific_force_m_s2, dtype=float)
        if not self.estimator.started:
            self.estimator.start(t_ns, gyro.angular_velocity_rad_s, radii, gyro.orientation_wxyz)
        self.last = self.estimator.update(
            t_ns,
            gyro.angular_velocity_rad_s,
            radii,
            joints=joints,
            in_flight=in_flight,
            specific_force_m_s2=gyro.specific_force_m_s2,
        )
        return self.last

    def estimated_model(self) -> RobotModel:
        """The robot with the estimated masses (the MPC plans with it)."""
        return self.estimator.estimated_model()
