"""How the simulated robot differs from the nominal one its controllers assume (ROS-free).

DESIGN.md section 3, "What controllers may read": the controllers read the IMU with
the scenario's noise and bias, and the joint states; the simulator flies the robot
as it really is. :class:`RobotErrors` says how that robot is wrong:

* ``mass_scale``: the lumped masses ``m_x``, ``m_y``, ``m_z`` of the robot flown
  are the nominal ones times these factors (:meth:`RobotErrors.plant_model`);
* ``hemi_inertia_kg_m2``: each hemi body's own principal moments of inertia about
  its centre (base axes), which the controllers' lumped-mass model (points, paper
  eq. 2) leaves out; the simulator adds both to the body's inertia tensor;
* ``gyro_noise_rad_s``, ``gyro_bias_rad_s``, ``noise_seed``: the rate gyro of
  ``/splitter/imu`` reads the true body rate plus a constant bias (body frame)
  plus white Gaussian noise of this standard deviation per axis and reading
  (:class:`Gyro`);
* ``actuator_lag_s``: every joint and tether command reaches the servos through a
  first-order lag of this time constant
  (:class:`splitter_model.actuators.CommandLag`, the one actuator-lag model).
* ``command_latency_s``: every joint and tether command reaches the servos this much
  after its stamp (a pure delay, before the lag), the way a bus or a network delays
  it;
* ``joint_effort_noise``, ``range_noise_m``, ``leg_force_noise_n``,
  ``accelerometer_noise_m_s2``: the joint effort sensors of ``/splitter/joint_states``
  (limb torques [N m], the reel's tether tension [N]), the hemis' rangefinders, their
  legs' load cells and the IMU's accelerometer (the specific force, base frame) read the
  truth plus white Gaussian noise of this standard deviation per reading
  (:class:`SensorNoise`, each sensor from its own generator so that the gyro's
  draws do not depend on them).

The defaults are the nominal robot: no error, and nothing drawn from a random
generator, so a run without errors is bit-identical to one before they existed.
Each field is a ``simulator`` node parameter (:func:`parameter_field`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.model import RobotModel
from splitter_msgs_py.core.parameter_fields import parameter_field
from splitter_sim.core.shape import hemi_body_inertia

MASS_SCALE_MAX = 10.0  # [-] a mass scale factor lies in (0, MASS_SCALE_MAX)
SEED_MAX = 2**31 - 1  # the largest noise seed (a ROS integer parameter holds it)


@dataclass(frozen=True)
class RobotErrors:
    """The simulated robot's mass, gyro and actuator errors (module docstring)."""

    mass_scale: tuple[float, float, float] = parameter_field(
        (1.0, 1.0, 1.0),
        "robot errors: factors on the simulated masses m_x, m_y, m_z, each in (0, 10) [-]",
        length=3,
        bounds=(0.0, MASS_SCALE_MAX),
    )
    hemi_inertia_kg_m2: tuple[float, float, float] = parameter_field(
        (0.0, 0.0, 0.0),
        "robot errors: each hemi body's own principal moments of inertia about its centre, "
        "base axes, which the point-mass model leaves out [kg m^2]",
        length=3,
        bounds=(0.0, 1e3),
    )
    gyro_noise_rad_s: float = parameter_field(
        0.0,
        "robot errors: white noise of the IMU's rate gyro, std per axis and reading [rad/s]",
        bounds=(0.0, 10.0),
    )
    gyro_bias_rad_s: tuple[float, float, float] = parameter_field(
        (0.0, 0.0, 0.0),
        "robot errors: constant bias of the IMU's rate gyro, body [rad/s]",
        length=3,
    )
    actuator_lag_s: float = parameter_field(
        0.0,
        "robot errors: first-order lag time constant of every joint and tether command "
        "(0: none) [s]",
        bounds=(0.0, 10.0),
    )
    command_latency_s: float = parameter_field(
        0.0,
        "robot errors: delay between a joint command's stamp and the servos receiving it "
        "(0: none) [s]",
        bounds=(0.0, 1.0),
    )
    joint_effort_noise: float = parameter_field(
        0.0,
        "robot errors: white noise of each joint effort reading, std [N m] (limbs) and "
        "[N] (tether tension)",
        bounds=(0.0, 100.0),
    )
    range_noise_m: float = parameter_field(
        0.0, "robot errors: white noise of each rangefinder reading, std [m]", bounds=(0.0, 10.0)
    )
    leg_force_noise_n: float = parameter_field(
        0.0,
        "robot errors: white noise of each leg load cell reading, std per axis [N]",
        bounds=(0.0, 1000.0),
    )
    accelerometer_noise_m_s2: float = parameter_field(
        0.0,
        "robot errors: white noise of the IMU's accelerometer, std per axis and reading [m/s^2]",
        bounds=(0.0, 100.0),
    )
    noise_seed: int = parameter_field(
        0, "robot errors: seed of the sensors' noise [-]", bounds=(0, SEED_MAX)
    )

    def __post_init__(self) -> None:
        for name in (
            "gyro_noise_rad_s",
            "actuator_lag_s",
            "command_latency_s",
            "joint_effort_noise",
            "range_noise_m",
            "leg_force_noise_n",
            "accelerometer_noise_m_s2",
        ):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"{name}: a number, got {value!r}")
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name}: must be finite and >= 0, got {value!r}")
            object.__setattr__(self, name, float(value))
        scale = _three_finite("mass_scale", self.mass_scale)
        if not all(0.0 < s < MASS_SCALE_MAX for s in scale):
            raise ValueError(f"mass_scale: each factor in (0, {MASS_SCALE_MAX:g}), got {scale}")
        object.__setattr__(self, "mass_scale", scale)
        object.__setattr__(
            self,
            "hemi_inertia_kg_m2",
            hemi_body_inertia(_three_finite("hemi_inertia_kg_m2", self.hemi_inertia_kg_m2)),
        )
        object.__setattr__(
            self, "gyro_bias_rad_s", _three_finite("gyro_bias_rad_s", self.gyro_bias_rad_s)
        )
        seed = self.noise_seed
        if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= SEED_MAX:
            raise ValueError(f"noise_seed: an integer in [0, {SEED_MAX}], got {seed!r}")

    @property
    def present(self) -> bool:
        """True when the robot differs from the nominal one (the noise seed alone is not)."""
        return (
            self.mass_scale != (1.0, 1.0, 1.0)
            or any(self.hemi_inertia_kg_m2)
            or self.gyro_noise_rad_s > 0.0
            or any(self.gyro_bias_rad_s)
            or self.actuator_lag_s > 0.0
            or self.command_latency_s > 0.0
            or self.joint_effort_noise > 0.0
            or self.range_noise_m > 0.0
            or self.leg_force_noise_n > 0.0
            or self.accelerometer_noise_m_s2 > 0.0
        )

    def plant_model(self, nominal: RobotModel) -> RobotModel:
        """The robot the simulator flies: ``nominal`` with its masses scaled."""
        sx, sy, sz = self.mass_scale
        return replace(
            nominal,
            body_mass_kg=nominal.body_mass_kg * sx,
            limb_mass_y_kg=nominal.limb_mass_y_kg * sy,
            limb_mass_z_kg=nominal.limb_mass_z_kg * sz,
        )


def _three_finite(name: str, value: object) -> tuple[float, float, float]:
    """``value`` as 3 finite floats; ValueError naming ``name`` otherwise."""
    try:
        if isinstance(value, str | bytes) or any(isinstance(v, bool) for v in value):  # type: ignore[union-attr]
            raise TypeError(name)
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: 3 finite numbers, got {value!r}") from None
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: 3 finite numbers, got {value!r}")
    return (float(arr[0]), float(arr[1]), float(arr[2]))


class Gyro:
    """The rate gyro of :class:`RobotErrors`: true rate + bias + white noise, per reading.

    One reading draws 3 normals (one per axis) from ``default_rng(noise_seed)``;
    without noise nothing is drawn, and without bias and noise the reading is the
    true rate itself.
    """

    def __init__(self, errors: RobotErrors) -> None:
        self.noise_rad_s = errors.gyro_noise_rad_s  # [rad/s] std per axis and reading
        self.bias_rad_s = np.asarray(errors.gyro_bias_rad_s, dtype=float)  # [rad/s] body
        self._rng = np.random.default_rng(errors.noise_seed)

    def read(self, w_true_rad_s: ArrayLike) -> NDArray[np.float64]:
        """The reading of the true body rate ``w_true_rad_s`` [rad/s]."""
        w = np.asarray(w_true_rad_s, dtype=float)
        if self.bias_rad_s.any():  # (none: the true rate as it is, -0.0 included)
            w = w + self.bias_rad_s
        if self.noise_rad_s > 0.0:
            w = w + self._rng.normal(0.0, self.noise_rad_s, 3)
        return w


class SensorNoise:
    """White Gaussian noise of one sensor: ``read`` adds it to the truth, per reading.

    ``stream`` numbers the sensor: its draws come from ``default_rng([seed, stream])``,
    so each sensor's noise is its own (the gyro draws from ``default_rng(seed)``).
    Without noise nothing is drawn and the reading is the truth itself.
    """

    EFFORT, RANGE, LEG_FORCE, ACCELEROMETER = 1, 2, 3, 4  # the streams

    def __init__(self, std: float, seed: int, stream: int) -> None:
        self.std = float(std)
        self._rng = np.random.default_rng([seed, stream])

    def read(self, truth: ArrayLike) -> NDArray[np.float64]:
        """The reading of ``truth`` (any shape)."""
        value = np.asarray(truth, dtype=float)
        if self.std > 0.0:
            value = value + self._rng.normal(0.0, self.std, value.shape)
        return value
