"""The flight estimator: body rate, gyro bias and mass ratios from the gyro and the joint encoders.

What a robot can measure: a rate gyro (true body rate plus a constant bias plus
white noise) and its joint encoders (so its radii, ``radii_from_joint_positions``).
What it cannot: its masses. An extended Kalman filter over

    x = [w (3) [rad/s], b (3) [rad/s], theta (2) [-]]

with ``theta = (ln(m_y / m_x), ln(m_z / m_x))`` relative to the nominal model's
ratios. The estimated robot keeps the nominal ``m_x`` and scales ``m_y``, ``m_z`` by
``exp(theta)``: a common scale of all masses scales the inertia, which changes
neither Euler's equations nor where the spin goes, so it is not observable from a
gyro and joint positions, and is not estimated (the estimated inertia is the true
one times ``m_x,nominal / m_x,true`` when the ratios are right).

Prediction over a control period ``dt`` between encoder readings ``k`` and ``k+1``:
torque-free flight conserves the angular momentum in the world, so in the body
frame ``dh/dt = -w x h`` with ``h = I(t) w`` and ``I(t)`` the model's principal
inertia along the measured radii (linear between the two readings); one RK4 step.
Bias and ratios are constant up to small random walks. Update: ``z = w + b + v``.

Observability: a biased rate does not satisfy Euler's equations (a steady spin
about y read with an x offset would nutate, and does not), and the ratios set how
the rate answers a change of shape (the momentum is conserved) and the nutation
frequency; both are seen while the robot tumbles or morphs. Contact (a ground
torque) breaks the conservation: :meth:`FlightEstimator.update` takes
``in_flight=False`` to freeze bias and ratios and follow the gyro.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.model import RobotModel
from splitter_model.rotations import quaternion_product
from splitter_msgs_py.core.parameter_fields import parameter_field

NX = 8  # [w (3), b (3), theta (2)]
W, B, THETA = slice(0, 3), slice(3, 6), slice(6, 8)
_POSITIVE = (1e-12, 1e3)


@dataclass(frozen=True)
class EstimatorConfig:
    """The estimator's noise model (the gyro's datasheet and how far the masses may be off)."""

    gyro_noise_rad_s: float = parameter_field(
        0.002, "gyro white noise, std per axis and reading [rad/s]", bounds=_POSITIVE
    )
    gyro_bias_prior_rad_s: float = parameter_field(
        0.01, "prior std of each gyro bias component [rad/s]", bounds=_POSITIVE
    )
    mass_ratio_prior: float = parameter_field(
        0.15,
        "prior std of ln(m_y/m_x) and ln(m_z/m_x) about the nominal model [-]",
        bounds=_POSITIVE,
    )
    rate_process_noise: float = parameter_field(
        2e-4,
        "rate process noise (unmodelled torque), std per sqrt(s) [rad/s/sqrt(s)]",
        bounds=_POSITIVE,
    )
    bias_random_walk: float = parameter_field(
        1e-5, "gyro bias random walk, std per sqrt(s) [rad/s/sqrt(s)]", bounds=_POSITIVE
    )
    mass_ratio_random_walk: float = parameter_field(
        1e-5, "mass ratio random walk, std per sqrt(s) [1/sqrt(s)]", bounds=_POSITIVE
    )


@dataclass(frozen=True)
class FlightEstimate:
    """The estimate at ``t_ns``: what the controllers fly on."""

    t_ns: int
    angular_velocity_rad_s: NDArray[np.float64]  # (3,) body [rad/s]
    gyro_bias_rad_s: NDArray[np.float64]  # (3,) body [rad/s]
    mass_ratios: NDArray[np.float64]  # (m_y/m_x, m_z/m_x) [-]
    masses_kg: NDArray[np.float64]  # (m_x, m_y, m_z) of the estimated model [kg]
    principal_inertia_kg_m2: NDArray[np.float64]  # (3,) the estimated model at the radii
    orientation_wxyz: NDArray[np.float64]  # (4,) world <- base, integrated rate
    covariance: NDArray[np.float64]  # (8, 8) of [w, b, theta]

    @property
    def rate_std_rad_s(self) -> NDArray[np.float64]:
        return np.sqrt(np.diag(self.covariance)[W])

    @property
    def bias_std_rad_s(self) -> NDArray[np.float64]:
        return np.sqrt(np.diag(self.covariance)[B])


def model_with_ratios(nominal: RobotModel, theta: ArrayLike) -> RobotModel:
    """The nominal robot with ``m_y``, ``m_z`` scaled by ``exp(theta)`` (``m_x`` kept)."""
    ty, tz = np.asarray(theta, dtype=float).reshape(2)
    return replace(
        nominal,
        limb_mass_y_kg=nominal.limb_mass_y_kg * math.exp(ty),
        limb_mass_z_kg=nominal.limb_mass_z_kg * math.exp(tz),
    )


def _principal_inertia(nominal: RobotModel, theta, radii):
    """Paper eq. (2) with the ratio-scaled limb masses, over CasADi symbols."""
    mx = nominal.body_mass_kg
    my = nominal.limb_mass_y_kg * ca.exp(theta[0])
    mz = nominal.limb_mass_z_kg * ca.exp(theta[1])
    rx2, ry2, rz2 = radii[0] ** 2, radii[1] ** 2, radii[2] ** 2
    m_tether = 2.0 * mx + 4.0 * my + 4.0 * mz
    return ca.vertcat(
        4.0 * my * ry2 + 4.0 * mz * rz2,
        m_tether * rx2 + 4.0 * mz * rz2,
        m_tether * rx2 + 4.0 * my * ry2,
    )


def _transition(nominal: RobotModel) -> ca.Function:
    """(x, radii_k, radii_k1, dt) -> (x_next, F = dx_next/dx): the prediction, one RK4 step."""
    x = ca.SX.sym("x", NX)
    r0 = ca.SX.sym("radii_k", 3)
    r1 = ca.SX.sym("radii_k1", 3)
    dt = ca.SX.sym("dt")
    theta = x[THETA]
    i0 = _principal_inertia(nominal, theta, r0)
    i1 = _principal_inertia(nominal, theta, r1)

    def rate(h, s):
        inertia = i0 + s * (i1 - i0)
        return -ca.cross(h / inertia, h)

    h = i0 * x[W]
    k1 = rate(h, 0.0)
    k2 = rate(h + 0.5 * dt * k1, 0.5)
    k3 = rate(h + 0.5 * dt * k2, 0.5)
    k4 = rate(h + dt * k3, 1.0)
    h_next = h + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    x_next = ca.vertcat(h_next / i1, x[B], x[THETA])
    return ca.Function(
        "estimator_transition",
        [x, r0, r1, dt],
        [x_next, ca.jacobian(x_next, x)],
    )


class FlightEstimator:
    """The EKF of the module docstring; one per robot, fed once per control tick."""

    def __init__(self, nominal: RobotModel, config: EstimatorConfig | None = None) -> None:
        self.nominal = nominal
        self.config = config or EstimatorConfig()
        self._f = _transition(nominal)
        self._x: NDArray[np.float64] | None = None
        self._p = np.zeros((NX, NX))
        self._radii: NDArray[np.float64] | None = None
        self._t_ns: int | None = None
        self._q = np.array([1.0, 0.0, 0.0, 0.0])

    @property
    def started(self) -> bool:
        return self._x is not None

    def start(self, t_ns: int, gyro_rad_s: ArrayLike, radii_m: ArrayLike, q_wxyz: ArrayLike):
        """First reading: the rate is the gyro's, the bias and ratios their priors."""
        c = self.config
        self._x = np.zeros(NX)
        self._x[W] = np.asarray(gyro_rad_s, dtype=float)
        self._p = np.diag(
            [c.gyro_bias_prior_rad_s**2 + c.gyro_noise_rad_s**2] * 3
            + [c.gyro_bias_prior_rad_s**2] * 3
            + [c.mass_ratio_prior**2] * 2
        )
        self._p[W, B] = self._p[B, W] = -np.eye(3) * c.gyro_bias_prior_rad_s**2
        self._radii = np.asarray(radii_m, dtype=float).copy()
        self._t_ns = int(t_ns)
        q = np.asarray(q_wxyz, dtype=float)
        self._q = q / np.linalg.norm(q)

    def update(
        self,
        t_ns: int,
        gyro_rad_s: ArrayLike,
        radii_m: ArrayLike,
        *,
        in_flight: bool = True,
    ) -> FlightEstimate:
        """Predict to ``t_ns`` with the encoders' radii, then correct with the gyro."""
        if self._x is None or self._t_ns is None or self._radii is None:
            raise RuntimeError("FlightEstimator.update before start")
        c = self.config
        z = np.asarray(gyro_rad_s, dtype=float)
        radii = np.asarray(radii_m, dtype=float)
        dt = (int(t_ns) - self._t_ns) * 1e-9
        if dt < 0.0:
            raise ValueError(f"estimator time went back: {t_ns} ns after {self._t_ns} ns")
        if dt > 0.0:
            w_before = self._x[W].copy()
            x_next, f = self._f(self._x, self._radii, radii, dt)
            f = np.asarray(f)
            x_next = np.asarray(x_next).reshape(NX)
            q_proc = np.diag(
                [c.rate_process_noise**2 * dt] * 3
                + [c.bias_random_walk**2 * dt] * 3
                + [c.mass_ratio_random_walk**2 * dt] * 2
            )
            if not in_flight:  # a contact torque: follow the gyro, keep bias and ratios
                f[THETA, :] = 0.0
                f[THETA, THETA] = np.eye(2)
                q_proc[W, W] += np.eye(3) * 1e2 * dt
            self._x = x_next
            self._p = f @ self._p @ f.T + q_proc
            self._integrate_attitude(0.5 * (w_before + self._x[W]), dt)
        # gyro update: z = w + b + v
        h = np.zeros((3, NX))
        h[:, W] = np.eye(3)
        h[:, B] = np.eye(3)
        s = h @ self._p @ h.T + np.eye(3) * c.gyro_noise_rad_s**2
        k = np.linalg.solve(s, h @ self._p).T
        self._x = self._x + k @ (z - self._x[W] - self._x[B])
        i_kh = np.eye(NX) - k @ h
        self._p = i_kh @ self._p @ i_kh.T + k @ k.T * c.gyro_noise_rad_s**2  # Joseph form
        self._p = 0.5 * (self._p + self._p.T)
        self._radii = radii.copy()
        self._t_ns = int(t_ns)
        return self.estimate()

    def _integrate_attitude(self, w: NDArray[np.float64], dt: float) -> None:
        angle = float(np.linalg.norm(w)) * dt
        if angle > 0.0:
            axis = w / np.linalg.norm(w)
            dq = (math.cos(angle / 2.0), *(math.sin(angle / 2.0) * axis))
            q = np.array(quaternion_product(tuple(self._q), dq), dtype=float)
            self._q = q / np.linalg.norm(q)

    def estimated_model(self) -> RobotModel:
        """The robot the controllers should plan with: nominal ``m_x``, estimated ratios."""
        theta = np.zeros(2) if self._x is None else self._x[THETA]
        return model_with_ratios(self.nominal, theta)

    def estimate(self) -> FlightEstimate:
        if self._x is None or self._t_ns is None or self._radii is None:
            raise RuntimeError("FlightEstimator.estimate before start")
        theta = self._x[THETA]
        model = model_with_ratios(self.nominal, theta)
        from splitter_model.model import principal_inertia

        ratios = np.array(
            [
                model.limb_mass_y_kg / model.body_mass_kg,
                model.limb_mass_z_kg / model.body_mass_kg,
            ]
        )
        return FlightEstimate(
            t_ns=self._t_ns,
            angular_velocity_rad_s=self._x[W].copy(),
            gyro_bias_rad_s=self._x[B].copy(),
            mass_ratios=ratios,
            masses_kg=np.array([model.body_mass_kg, model.limb_mass_y_kg, model.limb_mass_z_kg]),
            principal_inertia_kg_m2=principal_inertia(model, self._radii),
            orientation_wxyz=self._q.copy(),
            covariance=self._p.copy(),
        )
