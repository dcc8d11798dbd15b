"""The inertial-morphing optimal control problem (paper section VI), built once, symbolically.

The paper's state is ``[w (3), q (4, wxyz), Ixx, Iyy, Izz]`` with control ``dI``.
The principal moments are linear in the squared radii (eq. 2): ``I = M s``,
``s = (r_x^2, r_y^2, r_z^2)``. This OCP carries the inertia part of the state in
those coordinates, ``x = [w, q, s]``, ``u = [ds, sigma]`` with ``dI = M ds``: a
linear, invertible change of variables, so the optimum is the paper's, while
every hardware limit becomes a simple bound (see :mod:`.limits`).

The attitude q enters neither the rate dynamics nor any cost but J_q (Q_q,
Q_tq): without attitude tracking the OCP is built without it, ``x = [w, s]``
(:class:`StateLayout`), the same optimum for w and s with 6 states instead of
10 (a fatrop iteration is ~30 % cheaper; ``splitter bench mpc``).

Hardware limits as bounds:

* radius bounds: ``r_min^2 <= s_k <= r_max^2`` (exactly the reachable set; the
  paper's ``0 < I <= I_max`` follows from it);
* radius rates: ``|ds_k| <= 2 v dt rhat_k`` with ``rhat_k = max(r_min, r_0 - v (k+1) dt)``
  the smallest radius reachable by stage k + 1: ``|r_{k+1} - r_k| = |ds| / (r_k + r_{k+1})``
  and both radii are ``>= rhat_k``, so ``|dr| <= v dt`` (exact when the radius
  shrinks at full speed, conservative otherwise). The paper's box
  ``|dI| <= dI_max`` is implied (``dI_max`` is derived from the same speeds at the
  largest radii) and therefore not imposed twice: a duplicate bound makes the
  optimum degenerate for interior-point solvers;
* tether tension ``(w_y^2 + w_z^2) + sigma >= T_min / (m_x rhat_x,k)`` for k >= 1,
  i.e. ``T = m_x r_x (w_y^2 + w_z^2) >= T_min`` (the paper's ``m_x w_y^2 r_x`` with
  the z spin of :func:`splitter_model.model.tether_tension_3d`), soft with the
  slack ``sigma >= 0`` under an exact L1 penalty (zero whenever it can be met). A
  measured spin too slow for ``T_min`` asks only for the ``w_y^2 + w_z^2`` it has:
  the margin would otherwise make the MPC reel in and spin a slowly turning robot
  up (measured in lunar_jumping's second flight, launched at 0.05 rad/s: spun up to
  0.38 rad/s for the landing).

Discrete dynamics (paper eq. 13-16) with the *physically correct* gyroscopic
sign. The paper writes ``I_{k+1} w_{k+1} = I_k w_k + dt (w_k x I_k w_k)``; Euler's
equation ``d/dt (I w) + w x (I w) = 0`` gives a minus sign (DESIGN.md section 3),
and only the minus sign conserves the world-frame angular momentum::

    I_k = M s_k,  I_{k+1} = M (s_k + ds_k) = I_k + dI_k
    I_{k+1} w_{k+1} = I_k w_k - dt * w_k x (I_k w_k)
    q_{k+1} = normalize(q_k + dt/2 * q_k (x) [0, w_k])

Cost (paper eq. 17-21) ``J_w + J_q + J_c + J_t`` with diagonal weights, J_c on
``dI = M ds`` exactly as the paper weighs it. The quaternion term uses
``1/2 (1 - Re(e)^2)`` instead of the paper's ``1 - Re(e)`` (``e = q_ref^* (x) q``,
``Re(e) = q_ref . q``): both are ``theta^2 / 8`` to second order at zero error, but
this one is invariant under ``q -> -q`` (q and -q are the same attitude;
``1 - Re(e)`` drives a sign-flipped measurement half a turn the wrong way),
smooth everywhere (``1 - |Re(e)|`` has a kink at 180 deg) and, for unit
quaternions, a sum of squares ``1/2 |(E - q_ref q_ref^T) q|^2``.

Decision vector ordered stage by stage ``[x_0, u_0, x_1, u_1, ..., x_N]`` and
constraints ``[gap_0, path_0, gap_1, path_1, ...]``: the structure fatrop and
hpipm exploit. ``x_0`` is fixed by equal bounds (state feedback).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.reachable import ReachableSet
from splitter_model.rotations import quaternion_product
from splitter_mpc.core.limits import MorphingLimits
from splitter_msgs_py.core.parameter_fields import parameter_field

N_MEASURED = 10  # measured state [w (3), q (4, wxyz), principal moments (3)]
NU = 4  # [ds(3), tension slack]
NG_PATH = 1  # tension
W = slice(0, 3)
# q_w(3), r(3), q_t(3), q_q, q_tq, slack penalty, q_i(3), paper blend, spin-rate scales (2)
N_WEIGHTS = 18
N_MOMENTUM_TARGET = 5  # reference axis e (3), |H| [kg m^2/s], |w_ref| [rad/s]
OBJECTIVES = ("momentum", "paper")
INTEGRATORS = ("euler", "rk4")
_AXIS_EPS = 1e-9  # [rad/s] below this |w_ref| has no axis: the paper's J_w is used
_SLACK_QUADRATIC = 1e-4  # [s^4/rad^4] keeps the slack's Hessian regular
MAX_WEIGHT = 1e9  # [weight's unit] the largest weight a node parameter takes
MIN_EFFORT_WEIGHT = 1e-9  # [weight's unit] the smallest R a node parameter takes (R > 0)


@dataclass(frozen=True)
class StateLayout:
    """Where w, q and s sit in the OCP state: ``[w, q, s]``, or ``[w, s]`` without attitude."""

    attitude: bool = True

    @property
    def nx(self) -> int:
        return 10 if self.attitude else 6

    @property
    def w(self) -> slice:
        return W

    @property
    def q(self) -> slice:
        if not self.attitude:
            raise ValueError("this OCP carries no attitude (built without attitude tracking)")
        return slice(3, 7)

    @property
    def radii_sq(self) -> slice:
        return slice(7, 10) if self.attitude else slice(3, 6)


def _euler_step(
    x: ca.SX, u: ca.SX, dt_s: float, m: ca.DM, layout: StateLayout
) -> tuple[ca.SX, ca.SX | None]:
    """(h_{k+1}, q_{k+1}) by explicit Euler in angular momentum (the paper's eq. 13-16)."""
    w, s_sq = x[W], x[layout.radii_sq]
    momentum = ca.mtimes(m, s_sq) * w
    # Correct sign (the paper's eq. 13-14 print +): d/dt(I w) = -w x (I w).
    momentum_next = momentum - dt_s * ca.cross(w, momentum)
    if not layout.attitude:
        return momentum_next, None
    q = x[layout.q]
    return momentum_next, q + 0.5 * dt_s * ca.vertcat(*quaternion_product(q, ca.vertcat(0, w)))


_RK4_STAGES = (0.0, 0.5, 0.5, 1.0)  # [-] stage times as a share of the step


def _rk4(x0: ca.SX, rate, dt_s: float) -> ca.SX:
    """One classical RK4 step of ``dx/dt = rate(x, stage)`` (stage 0..3)."""
    k1 = rate(x0, 0)
    k2 = rate(x0 + 0.5 * dt_s * k1, 1)
    k3 = rate(x0 + 0.5 * dt_s * k2, 2)
    k4 = rate(x0 + dt_s * k3, 3)
    return x0 + dt_s / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


def _rk4_step(
    x: ca.SX, u: ca.SX, dt_s: float, m: ca.DM, layout: StateLayout
) -> tuple[ca.SX, ca.SX | None]:
    """(h_{k+1}, q_{k+1}) by classical RK4 of ``dh/dt = -w x h``, ``dq/dt = q (x) [0, w] / 2``.

    ``w = h / I(tau)`` with the inertia moving linearly from I_k to I_{k+1} over the
    step, as the setpoints played back at every control tick move it. w at a stage
    depends on h alone, so q is integrated after h with the stage rates of h's step.
    """
    inertia_0 = ca.mtimes(m, x[layout.radii_sq])
    d_inertia = ca.mtimes(m, u[0:3])
    stage_rates: list[ca.SX] = []

    def momentum_rate(h: ca.SX, stage: int) -> ca.SX:
        w = h / (inertia_0 + _RK4_STAGES[stage] * d_inertia)
        stage_rates.append(w)
        return -ca.cross(w, h)

    h1 = _rk4(inertia_0 * x[W], momentum_rate, dt_s)
    if not layout.attitude:
        return h1, None
    return h1, _rk4(
        x[layout.q],
        lambda q, stage: (
            0.5 * ca.vertcat(*quaternion_product(q, ca.vertcat(0, stage_rates[stage])))
        ),
        dt_s,
    )


def discrete_dynamics(
    x: ca.SX,
    u: ca.SX,
    dt_s: float,
    inertia_map: ArrayLike,
    integrator: str = "euler",
    *,
    layout: StateLayout = StateLayout(),
) -> ca.SX:
    """x_{k+1} = F(x_k, u_k) (module docstring); ``inertia_map`` is M with ``I = M s``.

    ``integrator``: ``"euler"`` (the paper's scheme) or ``"rk4"``; ``layout``: with
    or without the attitude q.
    """
    if integrator not in INTEGRATORS:
        raise ValueError(f"integrator must be one of {INTEGRATORS}, got {integrator!r}")
    m = ca.DM(np.asarray(inertia_map, dtype=float))
    s_next = x[layout.radii_sq] + u[0:3]
    step = _euler_step if integrator == "euler" else _rk4_step
    momentum_next, q_next = step(x, u, dt_s, m, layout)
    w_next = momentum_next / ca.mtimes(m, s_next)
    if q_next is None:
        return ca.vertcat(w_next, s_next)
    return ca.vertcat(w_next, q_next / ca.norm_2(q_next), s_next)


def dynamics_function(
    dt_s: float,
    inertia_map: ArrayLike,
    integrator: str = "euler",
    layout: StateLayout = StateLayout(),
) -> ca.Function:
    """F(x, u) as a CasADi function (SX)."""
    x = ca.SX.sym("x", layout.nx)
    u = ca.SX.sym("u", NU)
    return ca.Function(
        "F",
        [x, u],
        [discrete_dynamics(x, u, dt_s, inertia_map, integrator, layout=layout)],
        ["x", "u"],
        ["x_next"],
    )


@dataclass(frozen=True)
class ParameterLayout:
    """Where things sit in the parameter vector ``p``."""

    horizon: int

    @property
    def w_ref(self) -> slice:
        return slice(0, 3)

    @property
    def q_ref(self) -> slice:
        return slice(3, 3 + 4 * (self.horizon + 1))

    @property
    def weights(self) -> slice:
        start = 3 + 4 * (self.horizon + 1)
        return slice(start, start + N_WEIGHTS)

    @property
    def nominal_inertia(self) -> slice:
        return slice(self.weights.stop, self.weights.stop + 3)

    @property
    def momentum_target(self) -> slice:
        return slice(self.nominal_inertia.stop, self.nominal_inertia.stop + N_MOMENTUM_TARGET)

    @property
    def size(self) -> int:
        return self.momentum_target.stop


def _weight_field(
    default: float | tuple[float, float, float],
    description: str,
    *,
    min_value: float = 0.0,
    length: int | None = None,
) -> Any:
    """A weight the MPC node exposes as a live parameter in ``[min_value, MAX_WEIGHT]``."""
    return parameter_field(
        default, description, bounds=(min_value, MAX_WEIGHT), length=length, live=True
    )


@dataclass(frozen=True)
class MpcWeights:
    """The paper's diagonal weights (Tables I and II), the objective they weigh, additions.

    * ``objective``: how Q_w and Q_t are applied (module docstring, "Cost").
      ``"momentum"`` (option): on the direction of the body angular momentum
      ``(I w - |H| e) / I_nom`` and on the spin rate the configuration gives about
      the reference axis ``|H| / (e' I e) - w_spin``; it coincides with the paper's
      J_w at a spin about e and cannot be lowered by inflating the inertia.
      ``"paper"`` (default): the paper's J_w on the body rate ``w - w_ref``.
    * ``q_i``: weight of ``((I - I_nom) / I_nom)^2`` per stage (off by default),
      which pulls the limbs and the tether toward the nominal configuration;
    * ``tension_slack``: L1 penalty of a tether-tension shortfall [s^2/rad^2 per
      stage]: a 0.1 rad^2/s^2 shortfall costs as much as a 0.1 rad/s rate error
      at Q_w = 100.
    """

    q_w: tuple[float, float, float] = _weight_field(
        (100.0, 100.0, 100.0), "angular velocity weights Q_w", length=3
    )
    r: tuple[float, float, float] = _weight_field(
        (0.01, 1.0, 1.0),
        "control effort weights R (dI per step)",
        min_value=MIN_EFFORT_WEIGHT,
        length=3,
    )
    q_t: tuple[float, float, float] = _weight_field(
        (100.0, 10.0, 100.0), "terminal angular velocity weights Q_t", length=3
    )
    q_q: float = _weight_field(
        0.0,
        "quaternion tracking weight Q_q (live while > 0 from start-up: the attitude is then "
        "in the MPC's state)",
    )
    q_tq: float = _weight_field(0.0, "terminal quaternion weight Q_tq (live like q_q)")
    tension_slack: float = _weight_field(100.0, "L1 penalty of a tension shortfall [s^2/rad^2]")
    q_i: tuple[float, float, float] = (0.0, 0.0, 0.0)
    objective: str = parameter_field(
        "paper",
        "how q_w/q_t weigh the rate: momentum (rate across w_ref, reachable spin along it) "
        "or paper (w - w_ref)",
        choices=OBJECTIVES,
        live=True,
    )

    def __post_init__(self) -> None:
        if len(self.q_w) != 3 or len(self.r) != 3 or len(self.q_t) != 3 or len(self.q_i) != 3:
            raise ValueError("MpcWeights: q_w, r, q_t and q_i need 3 entries each")
        values = [*self.q_w, *self.r, *self.q_t, *self.q_i, self.q_q, self.q_tq, self.tension_slack]
        if not all(np.isfinite(v) and v >= 0.0 for v in values):
            raise ValueError(f"MpcWeights must be finite and >= 0, got {values}")
        if min(self.r) <= 0.0:
            raise ValueError("MpcWeights.r must be > 0 (the control Hessian must be regular)")
        if self.objective not in OBJECTIVES:
            raise ValueError(f"MpcWeights.objective must be one of {OBJECTIVES}")

    def per_stage(self, step_ratio: float) -> MpcWeights:
        """The weights of a prediction step ``step_ratio`` times the one they are given for.

        They keep one continuous-time cost on any grid. A running term weighs its
        error over the whole step, so Q_w, Q_q, q_i and the tension slack grow with
        the step. R weighs the per-step ``dI``: a rate held over the step costs
        ``R~ (dI / dt)^2 dt = (R~ / dt) dI^2``, so R falls with the step. The
        terminal weights Q_t and Q_tq are unchanged.
        """
        if not (math.isfinite(step_ratio) and step_ratio > 0.0):
            raise ValueError(f"step_ratio must be finite and > 0, got {step_ratio!r}")
        if step_ratio == 1.0:
            return self

        def scaled(values: tuple[float, ...], factor: float) -> tuple[float, float, float]:
            return tuple(float(v) * factor for v in values)  # type: ignore[return-value]

        return replace(
            self,
            q_w=scaled(self.q_w, step_ratio),
            r=scaled(self.r, 1.0 / step_ratio),
            q_q=self.q_q * step_ratio,
            q_i=scaled(self.q_i, step_ratio),
            tension_slack=self.tension_slack * step_ratio,
        )

    @property
    def tracks_attitude(self) -> bool:
        """Whether J_q weighs the attitude (the OCP then needs q in its state)."""
        return self.q_q > 0.0 or self.q_tq > 0.0

    def residual_scales(self, reference_axis: ArrayLike = (0.0, 0.0, 0.0)) -> NDArray[np.float64]:
        """The weights as OCP parameters: least-squares residual scales.

        ``e' Q e = 1/2 |sqrt(2 Q) e|^2``; the quaternion term ``Q_q/2 |P q|^2`` scales by
        ``sqrt(Q_q)``. Square roots are taken here, numerically, so the symbolic
        problem has no ``sqrt(p)`` whose derivative is infinite at a zero weight.
        The spin-rate term weighs the reference axis ``e`` (unit, or 0 without one)
        with ``e' Q_w e`` (``e' Q_t e`` at the end); the paper blend is 1 for the
        paper's objective and when there is no reference axis.
        """
        axis = np.asarray(reference_axis, dtype=float).reshape(3)
        has_axis = float(np.linalg.norm(axis)) > 0.5
        paper = self.objective == "paper" or not has_axis
        q_w, q_t = np.asarray(self.q_w, dtype=float), np.asarray(self.q_t, dtype=float)
        return np.array(
            [
                *np.sqrt(2.0 * q_w),
                *np.sqrt(2.0 * np.asarray(self.r, dtype=float)),
                *np.sqrt(2.0 * q_t),
                np.sqrt(self.q_q),
                np.sqrt(self.q_tq),
                self.tension_slack,
                *np.sqrt(2.0 * np.asarray(self.q_i, dtype=float)),
                1.0 if paper else 0.0,
                0.0 if paper else np.sqrt(2.0 * float(axis**2 @ q_w)),
                0.0 if paper else np.sqrt(2.0 * float(axis**2 @ q_t)),
            ],
            dtype=float,
        )


@dataclass
class MorphingOcp:
    """Symbolic OCP: decision vector, parameters, residuals, constraints and bounds."""

    horizon: int
    dt_s: float
    limits: MorphingLimits
    z: ca.SX  # decision vector
    p: ca.SX  # parameters
    residual: ca.SX  # r(z, p): objective = 1/2 |r|^2 + linear_cost
    linear_cost: ca.SX
    objective: ca.SX
    g: ca.SX  # constraints, stage-wise
    layout: ParameterLayout
    nx: list[int]
    nu: list[int]
    ng: list[int]
    equality: list[bool]
    gap_next_minus_f: bool
    state: StateLayout
    integrator: str = "euler"  # F's scheme (:data:`INTEGRATORS`)

    @property
    def n_z(self) -> int:
        return int(self.z.numel())

    @property
    def n_g(self) -> int:
        return int(self.g.numel())

    def x_index(self, k: int) -> slice:
        """Slice of x_k in z."""
        nx = self.state.nx
        start = k * (nx + NU)
        return slice(start, start + nx)

    def u_index(self, k: int) -> slice:
        """Slice of u_k in z (k < N)."""
        nx = self.state.nx
        start = k * (nx + NU) + nx
        return slice(start, start + NU)

    def split(self, z: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """States (N+1, nx) and controls (N, NU) of a decision vector."""
        z = np.asarray(z, dtype=float).ravel()
        n, nx = self.horizon, self.state.nx
        xs = np.empty((n + 1, nx))
        us = z[: n * (nx + NU)].reshape(n, nx + NU)
        xs[:n] = us[:, :nx]
        xs[n] = z[n * (nx + NU) :]
        return xs, us[:, nx:].copy()

    def join(self, xs: ArrayLike, us: ArrayLike) -> NDArray[np.float64]:
        """Inverse of :meth:`split`."""
        xs = np.asarray(xs, dtype=float)
        us = np.asarray(us, dtype=float)
        n = self.horizon
        return np.concatenate([np.hstack([xs[:n], us]).ravel(), xs[n]])

    @property
    def inertia_map(self) -> NDArray[np.float64]:
        """M with ``I = M s`` (the reachable set's map, eq. 2)."""
        return self.limits.reachable.inertia_map

    def dynamics(self) -> ca.Function:
        """F(x, u): the prediction model the gaps are written with."""
        return dynamics_function(self.dt_s, self.inertia_map, self.integrator, self.state)

    @property
    def tension_rows(self) -> NDArray[np.intp]:
        """Rows of the tension constraints of stages 1..N-1 in ``g`` (stage 0's is free)."""
        nx = self.state.nx
        return np.array([k * (nx + NG_PATH) + nx for k in range(1, self.horizon)], dtype=np.intp)

    def state_from_measurement(
        self,
        angular_velocity: ArrayLike,
        orientation_wxyz: ArrayLike,
        inertia: ArrayLike,
        reachable: ReachableSet | None = None,
    ) -> NDArray[np.float64]:
        """x_0 = (w, q / |q|, s): squared radii of the reachable moments nearest the measured.

        Nearest in principal inertia (:meth:`~splitter_model.reachable.ReachableSet.project`,
        the allocator's projection too) of ``reachable`` (default: the built model's).
        Without attitude states q is left out: ``(w, s)``.
        """
        s_sq = (reachable or self.limits.reachable).project(inertia)
        w = np.asarray(angular_velocity, dtype=float)
        if not self.state.attitude:
            return np.concatenate([w, s_sq])
        q = np.asarray(orientation_wxyz, dtype=float)
        return np.concatenate([w, q / np.linalg.norm(q), s_sq])

    def inertia_of(self, states: ArrayLike) -> NDArray[np.float64]:
        """Principal moments (..., 3) of states (..., nx)."""
        return np.asarray(states, dtype=float)[..., self.state.radii_sq] @ self.inertia_map.T

    def variable_bounds(
        self,
        x_init: ArrayLike,
        column_scale: ArrayLike = (1.0, 1.0, 1.0),
        state_offset: ArrayLike = (0.0, 0.0, 0.0),
        radius_bounds_m: tuple[ArrayLike, ArrayLike] | None = None,
    ) -> tuple[NDArray, NDArray]:
        """(lbz, ubz): x_0 = x_init, radius bounds, radius-rate bounds, slack >= 0.

        ``column_scale`` D and ``state_offset`` c [m^2]: the states carry ``D s + c`` (a
        robot with other masses and hemi bodies with their own moments,
        :meth:`~splitter_mpc.core.mpc.InertialMorphingMpc.set_mass_model`).
        ``radius_bounds_m``: (r_min, r_max) [m] that replace the model's (after a fault).
        """
        lim = self.limits
        if radius_bounds_m is None:
            r_min, r_max = lim.reachable.radius_min_m, lim.reachable.radius_max_m
        else:
            r_min, r_max = (np.asarray(b, dtype=float) for b in radius_bounds_m)
        d = np.asarray(column_scale, dtype=float)
        c = np.asarray(state_offset, dtype=float)
        n, nx, radii_sq = self.horizon, self.state.nx, self.state.radii_sq
        x0 = np.asarray(x_init, dtype=float)
        r_now = np.sqrt((x0[radii_sq] - c) / d)
        # both r_k and r_{k+1} are >= the smallest radius reachable by stage k + 1
        k = np.arange(1, n + 1)[:, None]
        r_low = np.maximum(r_min, r_now - lim.radius_rate_max_m_s * k * self.dt_s)
        rate = 2.0 * lim.radius_step_max_m * r_low * d  # (n, 3) [m^2] per step
        lo = np.full((n, nx + NU), -np.inf)
        hi = np.full((n, nx + NU), np.inf)
        s_min = r_min**2 * d + c
        s_max = r_max**2 * d + c
        lo[:, radii_sq] = s_min
        hi[:, radii_sq] = s_max
        lo[:, nx : nx + 3] = -rate
        hi[:, nx : nx + 3] = rate
        lo[:, nx + 3] = 0.0
        lo[0, :nx] = x0
        hi[0, :nx] = x0
        lo_n = np.full(nx, -np.inf)
        hi_n = np.full(nx, np.inf)
        lo_n[radii_sq] = s_min
        hi_n[radii_sq] = s_max
        return np.concatenate([lo.ravel(), lo_n]), np.concatenate([hi.ravel(), hi_n])

    def constraint_bounds(
        self,
        x_init: ArrayLike,
        column_scale: ArrayLike = (1.0, 1.0, 1.0),
        state_offset: ArrayLike = (0.0, 0.0, 0.0),
    ) -> tuple[NDArray, NDArray]:
        """(lbg, ubg): gaps = 0, tension rows (module docstring); ``column_scale`` and
        ``state_offset`` as in :meth:`variable_bounds`."""
        lim = self.limits
        n, nx = self.horizon, self.state.nx
        s_x = float(np.asarray(x_init, dtype=float)[self.state.radii_sq][0])
        s_x -= float(np.asarray(state_offset, dtype=float)[0])
        r_x = float(np.sqrt(s_x / float(np.asarray(column_scale, dtype=float)[0])))
        k = np.arange(n)
        r_low = np.maximum(lim.radius_min_m[0], r_x - lim.radius_rate_max_m_s[0] * k * self.dt_s)
        lo = np.zeros((n, nx + NG_PATH))
        hi = np.zeros((n, nx + NG_PATH))
        # A spin too slow for the margin keeps what it has: the tether's tension is its
        # centripetal load, so asking for more would make the MPC reel in and spin the
        # robot up (the allocator, likewise, only lets a slow spin reel in).
        w0 = np.asarray(x_init, dtype=float)[0:3]
        w_perp0_sq = float(w0[1] ** 2 + w0[2] ** 2)
        lo[:, nx] = np.minimum(lim.tension_min_n / (lim.body_mass_kg * r_low), w_perp0_sq)
        lo[0, nx] = -np.inf  # x_0 is measured: its tension is what it is
        hi[:, nx] = np.inf
        return lo.ravel(), hi.ravel()


def build_ocp(
    horizon: int,
    dt_s: float,
    limits: MorphingLimits,
    gap_next_minus_f: bool = False,
    integrator: str = "euler",
    *,
    attitude: bool = True,
) -> MorphingOcp:
    """Build the stage-wise OCP of the module docstring (SX, built once).

    ``gap_next_minus_f`` writes the gaps as ``x_{k+1} - F(x_k, u_k)`` (fatrop's
    structure detection requires it); the default ``F(x_k, u_k) - x_{k+1}`` is the
    ``[A B -I]`` block form hpipm expects. ``integrator`` is F's scheme.
    ``attitude``: carry q (needed by J_q); without it the attitude weights have
    no state to weigh and must be zero.
    """
    if horizon < 2:
        raise ValueError(f"horizon must be >= 2, got {horizon}")
    if not (np.isfinite(dt_s) and dt_s > 0.0):
        raise ValueError(f"dt_s must be finite and > 0, got {dt_s}")
    layout = ParameterLayout(horizon)
    p = ca.SX.sym("p", layout.size)
    w_ref = p[layout.w_ref]
    q_ref = ca.reshape(p[layout.q_ref], 4, horizon + 1)
    scales = p[layout.weights]
    s_w, s_r, s_t = scales[0:3], scales[3:6], scales[6:9]
    s_q, s_tq, slack_weight = scales[9], scales[10], scales[11]
    s_i, paper_blend, s_spin, s_spin_t = scales[12:15], scales[15], scales[16], scales[17]
    i_nom = p[layout.nominal_inertia]
    target = p[layout.momentum_target]
    axis, momentum_norm, spin_ref = target[0:3], target[3], target[4]
    inertia_map = limits.reachable.inertia_map
    m = ca.DM(inertia_map)
    state = StateLayout(attitude)
    nx, radii_sq = state.nx, state.radii_sq
    dynamics = dynamics_function(dt_s, inertia_map, integrator, state)

    xs = [ca.SX.sym(f"x{k}", nx) for k in range(horizon + 1)]
    us = [ca.SX.sym(f"u{k}", NU) for k in range(horizon)]

    def rate_error(x: ca.SX) -> ca.SX:
        """Paper: ``w - w_ref``; momentum: ``(1 - e e') w + e e' (I w - |H| e) / I_nom``.

        Blended by a parameter (1: paper). The momentum form weighs the body rate
        across the reference axis (zero at any spin about e) and, along e, how far
        the body momentum is from ``|H| e`` (tells +e from -e).
        """
        momentum = ca.mtimes(m, x[radii_sq]) * x[W]
        paper = x[W] - w_ref
        perpendicular = x[W] - axis * ca.dot(axis, x[W])
        along = axis * ca.dot(axis, (momentum - momentum_norm * axis) / i_nom)
        return paper_blend * paper + (1.0 - paper_blend) * (perpendicular + along)

    def spin_error(x: ca.SX) -> ca.SX:
        """Rate of a spin about e with this configuration, minus the reachable target."""
        axis_inertia = ca.dot(axis * axis, ca.mtimes(m, x[radii_sq])) + paper_blend
        return momentum_norm / axis_inertia - spin_ref

    def attitude_residual(x: ca.SX, k: int, scale: ca.SX) -> ca.SX:
        if not attitude:  # J_q needs q; its weights are checked to be zero (mpc.py)
            return ca.SX(0, 1)
        qr = q_ref[:, k]
        q = x[state.q]
        return scale * (q - qr * ca.dot(qr, q))  # sqrt(Q) (E - q_ref q_ref^T) q

    z_parts: list[ca.SX] = []
    g_parts: list[ca.SX] = []
    residuals: list[ca.SX] = []
    linear_cost = ca.SX(0)
    for k in range(horizon):
        x, u = xs[k], us[k]
        z_parts += [x, u]
        residuals += [
            s_w * rate_error(x),
            s_spin * spin_error(x),
            attitude_residual(x, k, s_q),
            s_i * (ca.mtimes(m, x[radii_sq]) - i_nom) / i_nom,
            s_r * ca.mtimes(m, u[0:3]),  # dI = M ds, weighed as the paper weighs dI
            np.sqrt(2.0 * _SLACK_QUADRATIC) * u[3],
        ]
        linear_cost += slack_weight * u[3]
        gap = dynamics(x, u) - xs[k + 1]
        g_parts += [-gap if gap_next_minus_f else gap, x[1] ** 2 + x[2] ** 2 + u[3]]
    x_n = xs[horizon]
    z_parts.append(x_n)
    residuals += [
        s_t * rate_error(x_n),
        s_spin_t * spin_error(x_n),
        attitude_residual(x_n, horizon, s_tq),
    ]
    residual = ca.vertcat(*residuals)
    return MorphingOcp(
        horizon=horizon,
        dt_s=dt_s,
        limits=limits,
        z=ca.vertcat(*z_parts),
        p=p,
        residual=residual,
        linear_cost=linear_cost,
        objective=0.5 * ca.sumsqr(residual) + linear_cost,
        g=ca.vertcat(*g_parts),
        layout=layout,
        nx=[nx] * (horizon + 1),
        nu=[NU] * horizon + [0],
        ng=[NG_PATH] * horizon + [0],
        equality=([True] * nx + [False] * NG_PATH) * horizon,
        gap_next_minus_f=gap_next_minus_f,
        state=state,
        integrator=integrator,
    )


def momentum_target(
    w_ref_rad_s: ArrayLike,
    momentum_norm: float,
    axis_inertia_range_kg_m2: tuple[float, float] | None = None,
) -> tuple[NDArray[np.float64], float]:
    """(reference axis e, reachable spin rate about e) of the momentum objective.

    ``e = w_ref / |w_ref|`` (0 when w_ref has no axis). A spin about e has the rate
    ``|H| / (e' I e)``: the reference's ``|w_ref|`` is clipped to what the moments
    within reach, ``axis_inertia_range_kg_m2`` (min, max), can give.
    """
    w_ref = np.asarray(w_ref_rad_s, dtype=float).reshape(3)
    speed = float(np.linalg.norm(w_ref))
    if not np.isfinite(momentum_norm) or momentum_norm < 0.0:
        raise ValueError(f"momentum_norm must be finite and >= 0, got {momentum_norm}")
    axis = w_ref / speed if speed > _AXIS_EPS else np.zeros(3)
    if axis_inertia_range_kg_m2 is not None and speed > _AXIS_EPS:
        low, high = axis_inertia_range_kg_m2
        speed = float(np.clip(speed, momentum_norm / high, momentum_norm / low))
    return axis, speed


def parameter_vector(
    layout: ParameterLayout,
    w_ref_rad_s: ArrayLike,
    q_ref_wxyz: ArrayLike,
    weights: MpcWeights,
    nominal_inertia_kg_m2: ArrayLike,
    *,
    momentum_norm: float = 0.0,
    axis_inertia_range_kg_m2: tuple[float, float] | None = None,
) -> NDArray[np.float64]:
    """Numeric ``p``: references (N+1 attitudes), weights, nominal inertia, momentum target.

    ``momentum_norm`` is |H| = |I_0 w_0| of the measured state [kg m^2/s] (the
    momentum objective's target is ``|H| e``).
    """
    q_ref = np.asarray(q_ref_wxyz, dtype=float).reshape(layout.horizon + 1, 4)
    axis, speed = momentum_target(w_ref_rad_s, momentum_norm, axis_inertia_range_kg_m2)
    return np.concatenate(
        [
            np.asarray(w_ref_rad_s, dtype=float).reshape(3),
            q_ref.ravel(),
            weights.residual_scales(axis),
            np.asarray(nominal_inertia_kg_m2, dtype=float).reshape(3),
            axis,
            [float(momentum_norm), speed],
        ]
    )
