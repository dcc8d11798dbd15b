"""The flight estimator: body rate, gyro bias and masses from the gyro and the joint sensors.

What a robot can measure: a rate gyro (true body rate plus a constant bias plus
white noise), its joint encoders (positions and velocities, so its radii and the
motion of each lumped mass) and its joint effort sensors (limb joint torques,
the reel's tether tension). What it cannot: its masses. An extended Kalman filter
over

    x = [w (3) [rad/s], b (3) [rad/s], theta (3) [-]]  (+ J (3) [kg m^2])

with ``theta = ln(m / m_nominal)`` for ``(m_x, m_y, m_z)`` and, when
``EstimatorConfig.hemi_inertia_prior_kg_m2`` is set, ``J`` each hemi body's own
principal moments about its centre, which the paper's point masses leave out (the
principal inertia is eq. 2 plus ``2 J``; prior mean 0, the nominal model). Only
``J_x`` is observed in a tumble: ``J_y`` and ``J_z`` sit beside the hemis' ``m r_x^2``
(0.1 % of ``I_yy`` at ``r_x`` = 2 m), so they wander within their prior, and matter
as little to the controllers.

Prediction over a control period ``dt`` between encoder readings ``k`` and ``k+1``:
torque-free flight conserves the angular momentum in the world, so in the body
frame ``dh/dt = -w x h`` with ``h = I(t) w`` and ``I(t)`` the model's principal
inertia along the measured radii (linear between the two readings); one RK4 step.
Bias, masses and body inertia are constant up to small random walks.

Updates:

* the gyro, ``z = w + b + v``. A biased rate does not satisfy Euler's equations,
  and the mass ratios set how the rate answers a change of shape; a common scale
  of all masses changes neither, so the gyro alone sees the ratios, and of those
  the limbs-against-body direction only weakly (10 % more limb mass moves
  ``Ixx/Iyy`` by ~3 %);
* the joint efforts, one control tick late. Each limb holds its lumped mass on
  its path through the spinning body, ``tau = J(q)^T m a`` with the mass's
  acceleration relative to the (free-falling) centre of mass
  ``a = w' x r + w x (w x r) + 2 w x v + a_rel``, and the reel holds hemi a's five
  masses, ``T = -sum m a_x``. Positions and velocities come from the encoders,
  ``a_rel`` from a central difference of the velocities (hence the tick of delay; a
  tick is used only while both one-sided differences stay small, as a servo swinging
  about its setpoint accelerates at the tick while the central difference cancels),
  ``w`` from the estimate and ``w'`` from Euler's equations; the accelerometer's
  specific force (drag, anything but gravity on the centre of mass) adds to every
  mass's acceleration. Linear in the masses:
  they, the common scale included, are observable whenever the robot spins.
  The bodies' own inertia loads no joint (a body turns with the base): the gyro sees
  it, through Euler's equations, once the efforts have fixed the masses.

Contact (ground forces and torques) breaks both models: :meth:`FlightEstimator.update`
takes ``in_flight=False`` to freeze bias and masses, skip the efforts and follow the gyro.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field, replace

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.joints import (
    LIMB_HEMI_SIGNS,
    LIMB_RADIUS_INDEX,
    N_LIMBS,
    TETHER_INDEX,
    limb_joints,
)
from splitter_model.kinematics import limb_forward_kinematics, limb_jacobian
from splitter_model.model import RobotModel, principal_inertia
from splitter_model.rotations import quaternion_product
from splitter_msgs_py.core.parameter_fields import parameter_field

NX = 9  # [w (3), b (3), theta (3)]; + 3 with the hemi bodies' inertia (HEMI)
W, B, THETA, HEMI = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12)
_POSITIVE = (1e-12, 1e3)
_HEMI_A_LIMBS = tuple(limb for limb in range(N_LIMBS) if LIMB_HEMI_SIGNS[limb] > 0.0)


@dataclass(frozen=True)
class EstimatorConfig:
    """The estimator's noise model (the sensors' datasheets and how far the masses may be off)."""

    gyro_noise_rad_s: float = parameter_field(
        0.002, "gyro white noise, std per axis and reading [rad/s]", bounds=_POSITIVE
    )
    gyro_bias_prior_rad_s: float = parameter_field(
        0.01, "prior std of each gyro bias component [rad/s]", bounds=_POSITIVE
    )
    mass_prior: float = parameter_field(
        0.15,
        "prior std of ln(m / m_nominal) for each of m_x, m_y, m_z [-]",
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
    mass_random_walk: float = parameter_field(
        1e-5, "random walk of ln(m), std per sqrt(s) [1/sqrt(s)]", bounds=_POSITIVE
    )
    joint_effort_noise: float = parameter_field(
        0.05,
        "joint effort sensor noise, std per joint and reading [N m] (limbs), [N] (tether)",
        bounds=_POSITIVE,
    )
    effort_model_error: float = parameter_field(
        0.05,
        "relative std of the effort model (finite-difference accelerations) [-]",
        bounds=(0.0, 10.0),
    )
    effort_max_acceleration_m_s2: float = parameter_field(
        0.05,
        "use a tick's efforts only while every mass's acceleration relative to the body "
        "(the encoders' differences into and out of the tick) stays below this: the "
        "servos' acceleration within a tick is not seen by the encoders [m/s^2]",
        bounds=_POSITIVE,
    )
    stance_force_threshold_n: float = parameter_field(
        2.0,
        "a hemi whose legs push harder than this is on the ground: no flight model [N]",
        bounds=(1e-3, 1e4),
    )
    effort_min_rate_rad_s: float = parameter_field(
        0.05,
        "use the efforts only while the body turns at least this fast: without a spin no "
        "centripetal load weighs the masses and the efforts are the servos' accelerations, "
        "which the encoders do not resolve [rad/s]",
        bounds=(0.0, 100.0),
    )
    use_joint_effort: bool = parameter_field(
        True, "update the masses from the joint efforts (when the joint states carry them)"
    )
    hemi_inertia_prior_kg_m2: float = parameter_field(
        0.0,
        "prior std of each of a hemi body's own principal moments of inertia (prior mean "
        "0, the paper's point masses); 0: the bodies are points, nothing estimated [kg m^2]",
        bounds=(0.0, 10.0),
    )
    hemi_inertia_random_walk: float = parameter_field(
        1e-6,
        "random walk of each hemi body's own moment, std per sqrt(s) [kg m^2/sqrt(s)]",
        bounds=_POSITIVE,
    )

    @property
    def state_size(self) -> int:
        """9, or 12 with the hemi bodies' own principal moments."""
        return NX + 3 if self.hemi_inertia_prior_kg_m2 > 0.0 else NX


@dataclass(frozen=True)
class JointReading:
    """One reading of the joint sensors (``names.JOINT_NAMES`` order)."""

    position: NDArray[np.float64]  # (25,) [rad] / tether [m]
    velocity: NDArray[np.float64] | None = None  # (25,) [rad/s] / [m/s]
    effort: NDArray[np.float64] | None = None  # (25,) [N m] / tether tension [N]


@dataclass(frozen=True)
class FlightEstimate:
    """The estimate at ``t_ns``: what the controllers fly on."""

    t_ns: int
    angular_velocity_rad_s: NDArray[np.float64]  # (3,) body [rad/s]
    gyro_bias_rad_s: NDArray[np.float64]  # (3,) body [rad/s]
    mass_ratios: NDArray[np.float64]  # (m_y/m_x, m_z/m_x) [-]
    masses_kg: NDArray[np.float64]  # (m_x, m_y, m_z) of the estimated model [kg]
    principal_inertia_kg_m2: NDArray[np.float64]  # (3,) the estimated robot at the radii
    orientation_wxyz: NDArray[np.float64]  # (4,) world <- base, integrated rate
    covariance: NDArray[np.float64]  # (9, 9) of [w, b, theta] (12, 12: and J)
    effort_updates: int = 0  # ticks whose joint efforts corrected the masses
    # (3,) each hemi body's own principal moments [kg m^2]; zero: point bodies
    hemi_inertia_kg_m2: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))

    @property
    def rate_std_rad_s(self) -> NDArray[np.float64]:
        return np.sqrt(np.diag(self.covariance)[W])

    @property
    def bias_std_rad_s(self) -> NDArray[np.float64]:
        return np.sqrt(np.diag(self.covariance)[B])


def nominal_masses(model: RobotModel) -> NDArray[np.float64]:
    """(m_x, m_y, m_z) of ``model`` [kg]."""
    return np.array([model.body_mass_kg, model.limb_mass_y_kg, model.limb_mass_z_kg])


def model_with_log_masses(nominal: RobotModel, theta: ArrayLike) -> RobotModel:
    """The nominal robot with ``m_x``, ``m_y``, ``m_z`` scaled by ``exp(theta)``."""
    mx, my, mz = nominal_masses(nominal) * np.exp(np.asarray(theta, dtype=float).reshape(3))
    return replace(nominal, body_mass_kg=mx, limb_mass_y_kg=my, limb_mass_z_kg=mz)


def _principal_inertia(nominal: RobotModel, theta, radii):
    """Paper eq. (2) with the scaled masses, over CasADi symbols."""
    mx = nominal.body_mass_kg * ca.exp(theta[0])
    my = nominal.limb_mass_y_kg * ca.exp(theta[1])
    mz = nominal.limb_mass_z_kg * ca.exp(theta[2])
    rx2, ry2, rz2 = radii[0] ** 2, radii[1] ** 2, radii[2] ** 2
    m_tether = 2.0 * mx + 4.0 * my + 4.0 * mz
    return ca.vertcat(
        4.0 * my * ry2 + 4.0 * mz * rz2,
        m_tether * rx2 + 4.0 * mz * rz2,
        m_tether * rx2 + 4.0 * my * ry2,
    )


def _transition(nominal: RobotModel, nx: int = NX) -> ca.Function:
    """(x, radii_k, radii_k1, dt) -> (x_next, F = dx_next/dx): the prediction, one RK4 step.

    ``nx`` 12: the states carry the hemi bodies' own moments ``J``: ``I = eq. 2 + 2 J``.
    """
    x = ca.SX.sym("x", nx)
    r0 = ca.SX.sym("radii_k", 3)
    r1 = ca.SX.sym("radii_k1", 3)
    dt = ca.SX.sym("dt")
    theta = x[THETA]
    i0 = _principal_inertia(nominal, theta, r0)
    i1 = _principal_inertia(nominal, theta, r1)
    if nx > NX:
        i0 = i0 + 2.0 * x[HEMI]
        i1 = i1 + 2.0 * x[HEMI]

    def rate(h, s):
        inertia = i0 + s * (i1 - i0)
        return -ca.cross(h / inertia, h)

    h = i0 * x[W]
    k1 = rate(h, 0.0)
    k2 = rate(h + 0.5 * dt * k1, 0.5)
    k3 = rate(h + 0.5 * dt * k2, 0.5)
    k4 = rate(h + dt * k3, 1.0)
    h_next = h + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    x_next = ca.vertcat(h_next / i1, x[B], x[THETA], *([x[HEMI]] if nx > NX else []))
    return ca.Function(
        "estimator_transition",
        [x, r0, r1, dt],
        [x_next, ca.jacobian(x_next, x)],
    )


@dataclass(frozen=True)
class _MassMotion:
    """The ten lumped masses' positions and velocities relative to the centre of mass."""

    positions_m: NDArray[np.float64]  # (10, 3) base [m]: hemi a body, its 4 limbs, hemi b ...
    velocities_m_s: NDArray[np.float64]  # (10, 3) base [m/s]
    jacobians: tuple[NDArray[np.float64], ...]  # per limb (3, 3) [m/rad]


def _mass_index(limb: int) -> int:
    """Index of limb ``limb``'s mass among the ten (body a, its 4 limbs, body b, ...)."""
    return limb + 1 + limb // 4


def mass_motion(model: RobotModel, joints: JointReading) -> _MassMotion:
    """Where the ten masses are and how they move, from the encoders (symmetric hemis:
    the centre of mass is the tether's midpoint)."""
    q = np.asarray(joints.position, dtype=float)
    qd = np.zeros_like(q) if joints.velocity is None else np.asarray(joints.velocity, dtype=float)
    positions = np.zeros((10, 3))
    velocities = np.zeros((10, 3))
    jacobians = []
    for body, sign in ((0, 1.0), (5, -1.0)):
        positions[body, 0] = 0.5 * sign * q[TETHER_INDEX]
        velocities[body, 0] = 0.5 * sign * qd[TETHER_INDEX]
    for limb in range(N_LIMBS):
        angles = q[limb_joints(limb)]
        jac = limb_jacobian(model, limb, angles)
        body = 0 if LIMB_HEMI_SIGNS[limb] > 0.0 else 5
        i = _mass_index(limb)
        positions[i] = positions[body] + limb_forward_kinematics(model, limb, angles)
        velocities[i] = velocities[body] + jac @ qd[limb_joints(limb)]
        jacobians.append(jac)
    return _MassMotion(positions, velocities, tuple(jacobians))


def effort_coefficients(
    motion: _MassMotion,
    relative_acceleration_m_s2: ArrayLike,
    w_rad_s: ArrayLike,
    w_dot_rad_s2: ArrayLike,
) -> NDArray[np.float64]:
    """(25, 3): each joint's effort per kg of m_x, m_y, m_z (``JOINT_NAMES`` order).

    A limb joint's torque is ``J^T m a`` of its mass, the tether's tension
    ``-sum m a_x`` over hemi a; ``a`` the mass's acceleration relative to the centre
    of mass (module docstring) plus, in ``relative_acceleration_m_s2``, the
    accelerometer's specific force (what accelerates the centre of mass besides
    gravity, which acts on every mass alike).
    """
    w = np.asarray(w_rad_s, dtype=float)
    w_dot = np.asarray(w_dot_rad_s2, dtype=float)
    r, v = motion.positions_m, motion.velocities_m_s
    a = (
        np.cross(w_dot, r)
        + np.cross(w, np.cross(w, r))
        + 2.0 * np.cross(w, v)
        + np.asarray(relative_acceleration_m_s2, dtype=float)
    )
    coefficients = np.zeros((TETHER_INDEX + 1, 3))
    for limb in range(N_LIMBS):
        group = LIMB_RADIUS_INDEX[limb]  # 1: m_y, 2: m_z
        coefficients[limb_joints(limb), group] = motion.jacobians[limb].T @ a[_mass_index(limb)]
    coefficients[TETHER_INDEX, 0] = -a[0, 0]
    for limb in _HEMI_A_LIMBS:
        coefficients[TETHER_INDEX, LIMB_RADIUS_INDEX[limb]] -= a[_mass_index(limb), 0]
    return coefficients


@dataclass(frozen=True)
class _Tick:
    """What the effort update keeps of one tick."""

    t_ns: int
    joints: JointReading
    motion: _MassMotion
    radii: NDArray[np.float64]
    w: NDArray[np.float64]
    specific_force: NDArray[np.float64]  # (3,) body [m/s^2], the accelerometer's


class FlightEstimator:
    """The EKF of the module docstring; one per robot, fed once per control tick."""

    def __init__(self, nominal: RobotModel, config: EstimatorConfig | None = None) -> None:
        self.nominal = nominal
        self.config = config or EstimatorConfig()
        self._nx = self.config.state_size
        self._f = _transition(nominal, self._nx)
        self._x: NDArray[np.float64] | None = None
        self._p = np.zeros((self._nx, self._nx))
        self._radii: NDArray[np.float64] | None = None
        self._t_ns: int | None = None
        self._q = np.array([1.0, 0.0, 0.0, 0.0])
        self._ticks: deque[_Tick] = deque(maxlen=3)
        self.effort_updates = 0

    @property
    def started(self) -> bool:
        return self._x is not None

    def start(self, t_ns: int, gyro_rad_s: ArrayLike, radii_m: ArrayLike, q_wxyz: ArrayLike):
        """First reading: the rate is the gyro's, the bias and masses their priors."""
        c = self.config
        self._x = np.zeros(self._nx)
        self._x[W] = np.asarray(gyro_rad_s, dtype=float)
        self._p = np.diag(
            [c.gyro_bias_prior_rad_s**2 + c.gyro_noise_rad_s**2] * 3
            + [c.gyro_bias_prior_rad_s**2] * 3
            + [c.mass_prior**2] * 3
            + [c.hemi_inertia_prior_kg_m2**2] * (self._nx - NX)
        )
        self._p[W, B] = self._p[B, W] = -np.eye(3) * c.gyro_bias_prior_rad_s**2
        self._radii = np.asarray(radii_m, dtype=float).copy()
        self._t_ns = int(t_ns)
        q = np.asarray(q_wxyz, dtype=float)
        self._q = q / np.linalg.norm(q)
        self._ticks.clear()

    def update(
        self,
        t_ns: int,
        gyro_rad_s: ArrayLike,
        radii_m: ArrayLike,
        *,
        in_flight: bool = True,
        joints: JointReading | None = None,
        specific_force_m_s2: ArrayLike = (0.0, 0.0, 0.0),
    ) -> FlightEstimate:
        """Predict to ``t_ns`` with the encoders' radii, then correct with the gyro and,
        with ``joints`` carrying efforts, the masses with the previous tick's efforts."""
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
            x_next = np.asarray(x_next).reshape(self._nx)
            q_proc = np.diag(
                [c.rate_process_noise**2 * dt] * 3
                + [c.bias_random_walk**2 * dt] * 3
                + [c.mass_random_walk**2 * dt] * 3
                + [c.hemi_inertia_random_walk**2 * dt] * (self._nx - NX)
            )
            if not in_flight:  # a contact torque: follow the gyro, keep bias and masses
                model = slice(THETA.start, self._nx)  # masses (and bodies' inertia)
                f[model, :] = 0.0
                f[model, model] = np.eye(self._nx - THETA.start)
                f[W, model] = 0.0  # the rate owes the masses nothing: no flight model
                q_proc[W, W] += np.eye(3) * 1e2 * dt
            self._x = x_next
            self._p = f @ self._p @ f.T + q_proc
            self._integrate_attitude(0.5 * (w_before + self._x[W]), dt)
        # gyro update: z = w + b + v
        h = np.zeros((3, self._nx))
        h[:, W] = np.eye(3)
        h[:, B] = np.eye(3)
        self._correct(h, z - self._x[W] - self._x[B], np.full(3, c.gyro_noise_rad_s**2))
        self._radii = radii.copy()
        self._t_ns = int(t_ns)
        if joints is None or not in_flight:
            self._ticks.clear()
        else:
            motion = mass_motion(self.nominal, joints)
            force = np.asarray(specific_force_m_s2, dtype=float)
            self._ticks.append(_Tick(int(t_ns), joints, motion, radii, self._x[W].copy(), force))
            if c.use_joint_effort and len(self._ticks) == 3:
                self._effort_update(*self._ticks)
        return self.estimate()

    def _correct(self, h: NDArray[np.float64], innovation, variances) -> None:
        """Kalman update with the measurement Jacobian ``h`` and diagonal noise (Joseph form)."""
        r = np.diag(np.asarray(variances, dtype=float))
        s = h @ self._p @ h.T + r
        k = np.linalg.solve(s, h @ self._p).T
        self._x = self._x + k @ innovation
        i_kh = np.eye(self._nx) - k @ h
        self._p = i_kh @ self._p @ i_kh.T + k @ r @ k.T
        self._p = 0.5 * (self._p + self._p.T)

    def _effort_update(self, before: _Tick, tick: _Tick, after: _Tick) -> None:
        """Correct the masses with ``tick``'s efforts (central differences around it)."""
        effort = tick.joints.effort
        if effort is None or tick.joints.velocity is None:
            return
        span_s = (after.t_ns - before.t_ns) * 1e-9
        lead_s, lag_s = (tick.t_ns - before.t_ns) * 1e-9, (after.t_ns - tick.t_ns) * 1e-9
        if lead_s <= 0.0 or lag_s <= 0.0:
            return
        relative_acceleration = (
            after.motion.velocities_m_s - before.motion.velocities_m_s
        ) / span_s
        c = self.config
        # Both one-sided differences, not only the central one: a servo that swings
        # about its velocity setpoint accelerates hard at the tick while the central
        # difference of its neighbours cancels (the reel at 1.3 m/s: 25 N one tick,
        # -11 N the next, a central difference of 0.05 m/s^2).
        for earlier, later, dt_s in ((before, tick, lead_s), (tick, after, lag_s)):
            one_sided = (later.motion.velocities_m_s - earlier.motion.velocities_m_s) / dt_s
            if np.abs(one_sided).max() > c.effort_max_acceleration_m_s2:
                return  # the limbs accelerate: the encoders do not see how within the tick
        if float(np.linalg.norm(tick.w)) < c.effort_min_rate_rad_s:
            return  # no spin: nothing weighs the masses
        masses = nominal_masses(self.nominal) * np.exp(self._x[THETA])
        model = replace(
            self.nominal,
            body_mass_kg=masses[0],
            limb_mass_y_kg=masses[1],
            limb_mass_z_kg=masses[2],
        )
        inertia = principal_inertia(model, tick.radii) + 2.0 * self._hemi_inertia()
        inertia_dot = (
            principal_inertia(model, after.radii) - principal_inertia(model, before.radii)
        ) / span_s
        w = tick.w
        w_dot = (-np.cross(w, inertia * w) - inertia_dot * w) / inertia
        coefficients = effort_coefficients(
            tick.motion, relative_acceleration + tick.specific_force, w, w_dot
        )
        predicted = coefficients @ masses
        rows = np.flatnonzero(np.abs(coefficients).sum(axis=1) > 0.0)
        h = np.zeros((rows.size, self._nx))
        h[:, THETA] = coefficients[rows] * masses  # d(effort)/d ln(m)
        variances = c.joint_effort_noise**2 + (c.effort_model_error * predicted[rows]) ** 2
        self._correct(h, np.asarray(effort, dtype=float)[rows] - predicted[rows], variances)
        self.effort_updates += 1

    def _integrate_attitude(self, w: NDArray[np.float64], dt: float) -> None:
        angle = float(np.linalg.norm(w)) * dt
        if angle > 0.0:
            axis = w / np.linalg.norm(w)
            dq = (math.cos(angle / 2.0), *(math.sin(angle / 2.0) * axis))
            q = np.array(quaternion_product(tuple(self._q), dq), dtype=float)
            self._q = q / np.linalg.norm(q)

    def _hemi_inertia(self) -> NDArray[np.float64]:
        """Each hemi body's own moments as estimated (zero: point bodies) [kg m^2]."""
        if self._x is None or self._nx == NX:
            return np.zeros(3)
        return self._x[HEMI].copy()

    def estimated_model(self) -> RobotModel:
        """The robot the controllers should plan with: the estimated masses."""
        theta = np.zeros(3) if self._x is None else self._x[THETA]
        return model_with_log_masses(self.nominal, theta)

    def estimate(self) -> FlightEstimate:
        if self._x is None or self._t_ns is None or self._radii is None:
            raise RuntimeError("FlightEstimator.estimate before start")
        model = model_with_log_masses(self.nominal, self._x[THETA])
        masses = nominal_masses(model)
        hemi = self._hemi_inertia()
        return FlightEstimate(
            t_ns=self._t_ns,
            angular_velocity_rad_s=self._x[W].copy(),
            gyro_bias_rad_s=self._x[B].copy(),
            mass_ratios=masses[1:] / masses[0],
            masses_kg=masses,
            principal_inertia_kg_m2=principal_inertia(model, self._radii) + 2.0 * hemi,
            orientation_wxyz=self._q.copy(),
            covariance=self._p.copy(),
            effort_updates=self.effort_updates,
            hemi_inertia_kg_m2=hemi,
        )
