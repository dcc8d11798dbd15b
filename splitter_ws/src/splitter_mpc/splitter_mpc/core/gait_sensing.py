"""What the gait phase manager knows of the body's motion, from the robot's own sensors.

The gait needs the stance of each hemi, the centre of mass's velocity (descending
after the last jump, at rest before LANDED) and its height (reported). A robot does
not get them from a simulator's odometry; it has (``splitter_model.sensors``):

* the IMU: attitude (its AHRS), body rate (the gyro) and the specific force at the
  centre of mass (the accelerometer);
* each hemi's downward rangefinder;
* each hemi's leg load cell (stance: the legs push harder than a threshold);
* the joint encoders (the tether: where each hemi is along the body x axis).

:class:`BodyMotionEstimator` is a strapdown integrator with the usual corrections:

* the velocity (world) integrates the accelerometer, ``dv/dt = R f + g`` (``g``
  the scenario's gravity, known to the robot: the planet it is on);
* the height and the vertical speed are a two-state Kalman filter on that
  vertical acceleration, corrected by every rangefinder with a return: the hemi
  body's height is ``range * cos`` of the ray's angle from the vertical (flat ground),
  the centre of mass's that minus the hemi's offset along the tether;
* a zero-velocity update (ZUPT) when both hemis are in stance and the body is still:
  the gyro under ``landed_angular_speed`` and the accelerometer within
  ``zupt_specific_force_m_s2`` of reading gravity alone (a robot sliding on the
  ground decelerates by friction, which the accelerometer reads).

The robot starts at rest (its initial velocity is zero); the horizontal position is
not estimated (the gait does not use it). ROS-free.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.rotations import quaternion_to_matrix
from splitter_model.sensors import hemi_height_from_range
from splitter_msgs_py.core.parameter_fields import parameter_field

_HEMI_SIGNS = (1.0, -1.0)  # hemi a at +x, hemi b at -x of the base frame


@dataclass(frozen=True)
class BodySensingConfig:
    """The sensors' noise as the gait's estimator assumes it, and the ZUPT's thresholds."""

    gravity_m_s2: float = parameter_field(
        0.0, "gravity where the robot is (magnitude, world -z) [m/s^2]", bounds=(0.0, 100.0)
    )
    range_noise_m: float = parameter_field(
        0.01, "rangefinder noise, std per reading [m]", bounds=(1e-6, 10.0)
    )
    accelerometer_noise_m_s2: float = parameter_field(
        0.05, "accelerometer noise and vibration, std per reading [m/s^2]", bounds=(1e-6, 100.0)
    )
    zupt_specific_force_m_s2: float = parameter_field(
        0.05,
        "at rest: the accelerometer reads gravity alone within this [m/s^2]",
        bounds=(1e-6, 100.0),
    )
    zupt_angular_speed_rad_s: float = parameter_field(
        0.05, "at rest: the gyro reads less than this [rad/s]", bounds=(1e-6, 10.0)
    )


@dataclass(frozen=True)
class ImuReading:
    """What the gait takes of an IMU message."""

    orientation_wxyz: NDArray[np.float64]  # (4,) world <- base
    angular_velocity_rad_s: NDArray[np.float64]  # (3,) body [rad/s]
    specific_force_m_s2: NDArray[np.float64]  # (3,) body [m/s^2]


@dataclass(frozen=True)
class BodyMotion:
    """The estimate at one tick."""

    position_m: NDArray[np.float64]  # (3,) world: (0, 0, height of the centre of mass)
    velocity_m_s: NDArray[np.float64]  # (3,) world
    height_measured: bool  # a rangefinder corrected the height at this tick
    at_rest: bool  # the zero-velocity update applied at this tick


class BodyMotionEstimator:
    """The strapdown estimator of the module docstring, fed once per control tick."""

    def __init__(self, config: BodySensingConfig | None = None) -> None:
        self.config = config or BodySensingConfig()
        self._t_ns: int | None = None
        self._vertical = np.zeros(2)  # [height [m], vertical speed [m/s]]
        self._p = np.diag([1e2, 1e-4])  # height unknown, the robot starts at rest
        self._horizontal = np.zeros(2)  # [m/s] world x, y
        self._acceleration = np.zeros(3)  # [m/s^2] world, last tick's

    def update(
        self,
        t_ns: int,
        imu: ImuReading,
        ranges_m: ArrayLike,
        stance: tuple[bool, bool],
        radius_x_m: float,
    ) -> BodyMotion:
        """Advance to ``t_ns`` with this tick's readings (``stance`` from the leg load cells)."""
        c = self.config
        rot = quaternion_to_matrix(imu.orientation_wxyz)
        specific = rot @ np.asarray(imu.specific_force_m_s2, dtype=float)
        acceleration = specific - np.array([0.0, 0.0, c.gravity_m_s2])
        if self._t_ns is not None:
            dt = (int(t_ns) - self._t_ns) * 1e-9
            if dt < 0.0:
                raise ValueError(f"body motion: time went back ({t_ns} ns after {self._t_ns} ns)")
            mean = 0.5 * (acceleration + self._acceleration)  # trapezoid over the tick
            self._horizontal += mean[:2] * dt
            f = np.array([[1.0, dt], [0.0, 1.0]])
            self._vertical = f @ self._vertical + np.array([0.5 * dt * dt, dt]) * mean[2]
            q = c.accelerometer_noise_m_s2**2 * np.array(
                [[dt**4 / 4.0, dt**3 / 2.0], [dt**3 / 2.0, dt * dt]]
            )
            self._p = f @ self._p @ f.T + q
        self._t_ns = int(t_ns)
        self._acceleration = acceleration
        measured = False
        for sign, range_m in zip(_HEMI_SIGNS, np.asarray(ranges_m, dtype=float), strict=True):
            hemi_height = hemi_height_from_range(float(range_m), rot)
            if hemi_height is None:
                continue
            com_height = hemi_height - sign * radius_x_m * float(rot[2, 0])
            self._correct(np.array([1.0, 0.0]), com_height, c.range_noise_m**2)
            measured = True
        still = (
            all(stance)
            and float(np.linalg.norm(imu.angular_velocity_rad_s)) < c.zupt_angular_speed_rad_s
            and abs(float(np.linalg.norm(specific)) - c.gravity_m_s2) < c.zupt_specific_force_m_s2
            and float(np.linalg.norm(specific[:2])) < c.zupt_specific_force_m_s2
        )
        if still:
            self._horizontal[:] = 0.0
            self._correct(np.array([0.0, 1.0]), 0.0, 1e-6)
        return BodyMotion(
            position_m=np.array([0.0, 0.0, self._vertical[0]]),
            velocity_m_s=np.array([*self._horizontal, self._vertical[1]]),
            height_measured=measured,
            at_rest=still,
        )

    def _correct(self, h: NDArray[np.float64], z: float, variance: float) -> None:
        s = float(h @ self._p @ h) + variance
        k = self._p @ h / s
        self._vertical = self._vertical + k * (z - float(h @ self._vertical))
        self._p = self._p - np.outer(k, h @ self._p)
        self._p = 0.5 * (self._p + self._p.T)


def leg_stance_force_n(leg_force_base_n: ArrayLike) -> float:
    """How hard a hemi's legs push [N] (the load cell's magnitude)."""
    force = np.asarray(leg_force_base_n, dtype=float)
    return float(math.sqrt(float(force @ force)))
