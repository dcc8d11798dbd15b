"""The inertial-morphing MPC: the OCP of :mod:`.ocp` built once, solved warm.

:class:`InertialMorphingMpc` owns one back-end (:mod:`.solvers`), built once with
every changing number a parameter (references, weights, nominal inertia) or a
bound (measured state, radius-rate limits), and the primal-dual solution of the
last solve, which it shifts by the elapsed number of prediction steps to
warm-start the next one (the tail is rolled out with zero control). ROS-free.

Two formulations (``MpcSettings`` + ``MpcWeights.objective``)
-------------------------------------------------------------
* **paper** (``MpcSettings()``, ``MpcWeights()``; section VI, Table I): N = 50 x
  10 ms, explicit Euler, J_w on ``w - w_ref``, with the correct gyroscopic sign
  and the hardware limits. The spin_stabilization ``paper_mpc`` variant.
* **momentum** (``MOMENTUM_MPC_SETTINGS`` + ``objective="momentum"``; node
  parameters ``objective: momentum, horizon: 25, dt_s: 0.1, integrator: rk4,
  weights_step_s: 0.05``; the ``mpc`` variant of spin_stabilization): a 2.5 s
  prediction, 25 RK4 steps of 100 ms, and the paper's weights (given per 50 ms
  step, :meth:`~splitter_mpc.core.ocp.MpcWeights.per_stage`) on what a spin about
  ``e = w_ref / |w_ref|`` means:
  the body rate *across* e, ``(1 - e e') w`` (zero at any spin about e), the body
  momentum *along* e, ``e'(I w - |H| e) / I_nom`` (tells +e from -e), and the spin
  rate the configuration gives about e, ``|H| / (e' I e)``, against the reachable
  ``clip(|w_ref|, |H| / I_e,max, |H| / I_e,min)``. At a spin about e it is the
  paper's J_w; elsewhere it cannot be lowered by inflating the inertia
  (``h = I w`` only rotates in the body, ``|h| = |H|``).

Why (spin_stabilization, ``splitter run spin_stabilization --no-ros``):
H is conserved; the body is nearly axisymmetric about x (Ixx = 0.48 << Iyy =
Izz = 141.4), and aligning H with body y means rotating the body ~135 deg about
x, driven by ``w_x = h_x / Ixx`` which only the asymmetry ``Iyy - Izz`` (<= Ixx)
builds: ``phi'' = -(|H|^2 / 2)(1/Izz - 1/Iyy)/Ixx sin(2 phi)``, a pendulum whose
stiffness the limbs switch (|phi''| <= ~0.8 rad/s^2) and whose rate the limbs
rescale (``w_x = h_x / Ixx``, Ixx from 0.14 to 1.9). The manoeuvre takes ~2 s:
the paper's 0.5 s horizon cannot see it, and its J_w on ``w_y - 1`` rewards
inflating the inertia (``w = H / I``), so the paper's MPC inflates and turns
slowly. The momentum formulation sees the whole turn and only asks for what is
reachable. Measured (library loop, same plant, allocator, gait machine):

=================  =======  ======  ========
metric             paper's  paper   momentum
                   figure   mode    (mpc)
=================  =======  ======  ========
residual_wx rad/s  0.004    0.11    0.0036
residual_wz rad/s  0.006    0.28    0.0018
wy_final rad/s     1.28     1.07    1.105
alignment |wy|/|w|  -       0.971   1.000
time_constant s    1.3      3.9     1.63
settling_time s    2.8      6.9     2.97
=================  =======  ======  ========

Weighing the rate across e (not the momentum ``h_x / I_nom``) matters: with
``h_x / I_nom`` the plan shrinks Ixx to turn faster (``w_x = h_x / Ixx``, up to
3 rad/s) and leaves a 0.03 rad/s nutation that decays over seconds; with the
body rate it damps the nutation as it turns. The grid: 50 explicit-Euler steps of
50 ms with the weights per stage (the first version) give 0.0036 / 0.0023 rad/s
and 2.955 s; 25 RK4 steps of 100 ms with the same weights per stage 0.0033 /
0.0025 and 2.995 s (R, on a dI twice as large, weighs four times as much against
the rates); with the weights kept per 50 ms (one continuous-time cost) 0.0036 /
0.0018 and 2.97 s, with half the stages: the hardest re-plans take 34 and 27
fatrop iterations instead of 41 and 34 (``splitter bench mpc``: p99 6-8 ms
against 10-13).

w_y is not set by the reference: a final spin about y is ``|H| / Iyy``
(|H| = 179.9 kg m^2/s). w_ref = 1 needs Iyy = 180 > I_max = 162.9, so the
closest reachable is 1.10 rad/s (r_x at 3.0 m). The paper's 1.28 rad/s with
"equal energy at t = 0 and 8 s" is exactly ``|H| / Iyy(0)``: its inertia ended
where it started. With the paper's printed + sign in the model a prototype
settles about -y (w_y = -1.27), against the reference, through inertias that
violate the triangle inequality.

Orientation tracking (Table II): the paper's reference ``q0 (x) exp(w_ref t / 2)``
turns at +1 rad/s about body y from the initial attitude while the body starts
with w_y = -0.5 rad/s and H 45 deg away from the reference axis, so no inertia
history can follow it. The scenario flies the reachable reference instead
(gait mode ``momentum_aligned``: body y turned onto the world H first,
:func:`splitter_mpc.core.gait.momentum_aligned_attitude`); what is left to track
is the phase of the spin about H, which the morphing sets through Iyy.

Solve time: without attitude tracking the OCP carries no q
(:func:`settings_for_weights`); the hardest re-plans are the first ones of a
turn (30-40 fatrop iterations against a median of 18), because the actuators
lag the plan (joint acceleration limits: over a 0.1 s re-plan the limbs move
at ~0.4 m/s where the plan asks for 1-2 m/s), so each measured state is far from the
last prediction (up to 0.5 rad/s in w_x = h_x / Ixx). With ideal actuators the
second-hardest re-plan takes 25 iterations, not 34.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace
from functools import partial

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.model import RobotModel
from splitter_model.reachable import ReachableSet, inertia_map
from splitter_mpc.core.limits import MorphingLimits, morphing_limits
from splitter_mpc.core.ocp import (
    INTEGRATORS,
    N_MEASURED,
    NG_PATH,
    NU,
    MorphingOcp,
    MpcWeights,
    build_ocp,
    dynamics_function,
    momentum_target,
    parameter_vector,
)
from splitter_mpc.core.solver_worker import (
    STATUS_NON_FINITE_DATA,
    SolverWorker,
    failed_result,
    non_finite_fields,
)
from splitter_mpc.core.solvers import (
    BOUNDED_SOLVERS,
    SOLVERS,
    Closable,
    ProblemInstance,
    SolverOptions,
    SolverResult,
    close_part,
    make_backend,
)
from splitter_msgs_py.core.parameter_fields import FRACTION, parameter_field

_LOG = logging.getLogger(__name__)
NS_PER_S = 1_000_000_000


def checked_radius_bounds(
    radius_min_m: ArrayLike | None, radius_max_m: ArrayLike | None
) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """(r_min, r_max) [m] as arrays (3,), None for None; ValueError unless 0 < min < max."""
    if radius_min_m is None or radius_max_m is None:
        return None
    lo = np.asarray(radius_min_m, dtype=float).reshape(3)
    hi = np.asarray(radius_max_m, dtype=float).reshape(3)
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(0.0 < lo)):
        raise ValueError(f"radius bounds must be finite and > 0, got {lo}, {hi}")
    if not np.all(lo < hi):
        raise ValueError(f"radius bounds need min < max, got {lo}, {hi}")
    return lo, hi


@dataclass(frozen=True)
class MpcSettings:
    """Horizon, integrator, solver and hardware margins.

    Default: the paper's (Table I, section VI), N = 50 steps of 10 ms with explicit
    Euler. :data:`MOMENTUM_MPC_SETTINGS` is the long-horizon formulation (25 x 100 ms)
    to pair with ``MpcWeights(objective="momentum")`` (module docstring).
    ``attitude_states``: the OCP carries the attitude q (the paper's state); it
    must when the weights track the attitude, and need not otherwise
    (:func:`settings_for_weights` decides; without q a solve is ~30 % faster).
    """

    horizon: int = parameter_field(50, "prediction horizon N [steps]", bounds=(2, 1000))
    dt_s: float = parameter_field(  # [s] prediction step
        0.01, "prediction step [s] (whole milliseconds)", bounds=(0.001, 1.0)
    )
    integrator: str = parameter_field(
        "euler", "prediction model integrator (euler: the paper's)", choices=INTEGRATORS
    )
    solver: str = parameter_field("fatrop", "optimisation back-end", choices=SOLVERS)
    options: SolverOptions = field(default_factory=SolverOptions)
    tension_min_n: float = parameter_field(  # [N] taut-tether margin (soft)
        1.0, "taut-tether margin [N]", bounds=(0.0, 1e4)
    )
    radius_rate_scale: float = parameter_field(  # share of the actuator radius speeds
        1.0, "share of the actuator radius speeds planned", bounds=FRACTION
    )
    attitude_states: bool = True
    # [s] the prediction step the weights are given for (None or 0: per stage, read as
    # None); see MpcWeights.per_stage
    weights_step_s: float | None = parameter_field(
        0.0,
        "prediction step the weights are given for [s] (0: per stage); the stage weights "
        "then keep one continuous-time cost",
        bounds=(0.0, 1.0),
    )

    def __post_init__(self) -> None:
        if not (isinstance(self.horizon, int) and 2 <= self.horizon <= 1000):
            raise ValueError(f"horizon must be an int in [2, 1000], got {self.horizon!r}")
        if not (math.isfinite(self.dt_s) and 0.0 < self.dt_s <= 1.0):
            raise ValueError(f"dt_s must be in (0, 1] s, got {self.dt_s!r}")
        if round(self.dt_s * NS_PER_S) % 1_000_000 != 0:
            raise ValueError(f"dt_s must be a whole number of milliseconds, got {self.dt_s!r}")
        if self.integrator not in INTEGRATORS:
            raise ValueError(f"integrator must be one of {INTEGRATORS}, got {self.integrator!r}")
        if self.solver not in SOLVERS:
            raise ValueError(f"solver must be one of {SOLVERS}, got {self.solver!r}")
        if self.weights_step_s == 0.0:
            object.__setattr__(self, "weights_step_s", None)
        step = self.weights_step_s
        if step is not None and not (math.isfinite(step) and step > 0.0):
            raise ValueError(f"weights_step_s must be None, 0 or finite and > 0, got {step!r}")

    @property
    def dt_ns(self) -> int:
        return round(self.dt_s * NS_PER_S)

    @property
    def weights_step_ratio(self) -> float:
        """Prediction step over the step the weights are given for (1: per stage)."""
        return 1.0 if self.weights_step_s is None else self.dt_s / self.weights_step_s


PAPER_MPC_SETTINGS = MpcSettings(horizon=50, dt_s=0.01, integrator="euler")
# spin_stabilization's: 2.5 s in 25 RK4 steps, Table I's weights per 50 ms
MOMENTUM_MPC_SETTINGS = MpcSettings(horizon=25, dt_s=0.1, integrator="rk4", weights_step_s=0.05)


def settings_for_weights(settings: MpcSettings, weights: MpcWeights) -> MpcSettings:
    """``settings`` with the attitude in the OCP state exactly when ``weights`` track it."""
    return replace(settings, attitude_states=weights.tracks_attitude)


@dataclass(frozen=True)
class PlanRequest:
    """What one solve plans from: the state measured at ``t_ns``, the references, the weights.

    ``state`` = (w (3), q (4, wxyz), principal moments (3)); ``q_ref_wxyz`` is the
    attitude reference at each of the N+1 prediction times; ``nominal_inertia_kg_m2``
    (None: the measured one) is the I_nom of the momentum objective's rate scale and
    of the nominal-configuration term.
    """

    t_ns: int  # [ns]
    state: ArrayLike
    w_ref_rad_s: ArrayLike  # [rad/s]
    q_ref_wxyz: ArrayLike  # (N+1, 4)
    weights: MpcWeights
    nominal_inertia_kg_m2: ArrayLike | None = None  # [kg m^2]


@dataclass(frozen=True)
class MpcPlan:
    """A solved plan: predicted states from ``t_ns`` on the ``dt_ns`` grid."""

    t_ns: int  # [ns] time of x_0
    dt_ns: int  # [ns]
    angular_velocity: NDArray[np.float64]  # (N+1, 3) predicted [rad/s]
    orientation: NDArray[np.float64] | None  # (N+1, 4) predicted; None: OCP without attitude
    # (N+1, 3) [kg m^2] the planned shape as the built model's principal moments (what
    # the allocator, which allocates with that model, turns back into the planned radii;
    # with set_mass_model the robot's own moments differ from these by its masses)
    inertia: NDArray[np.float64]
    radii: NDArray[np.float64]  # (N+1, 3) planned radii [m]
    result: SolverResult

    def setpoint_at(self, t_ns: int, tick_ns: int | None = None) -> NDArray[np.float64]:
        """Inertia to command at ``t_ns``: the plan's value at the end of that control tick.

        The actuators are commanded the inertia the plan reaches at the end of the
        tick of length ``tick_ns`` (default: one prediction step) that contains
        ``t_ns``, interpolated linearly inside a prediction step (the MPC's RK4
        model moves the inertia linearly over a step). With ``tick_ns = dt_ns``
        it is ``inertia[j + 1]`` for ``t_ns`` in step j. Past the horizon the last
        value holds.
        """
        tick = self.dt_ns if tick_ns is None else int(tick_ns)
        elapsed = max(0, int(t_ns) - self.t_ns)
        end = (elapsed // tick + 1) * tick  # [ns] after t_ns of the plan
        j, rest = divmod(end, self.dt_ns)
        last = len(self.inertia) - 1
        if j >= last:
            return self.inertia[last].copy()
        share = rest / self.dt_ns
        return (1.0 - share) * self.inertia[j] + share * self.inertia[j + 1]


def morphing_problem(
    model: RobotModel, settings: MpcSettings
) -> tuple[MorphingLimits, MorphingOcp]:
    """The limits and the OCP that ``settings`` describe for ``model``."""
    s = settings
    limits = morphing_limits(model, s.dt_s, s.tension_min_n, s.radius_rate_scale)
    ocp = build_ocp(
        s.horizon,
        s.dt_s,
        limits,
        gap_next_minus_f=s.solver == "fatrop",
        integrator=s.integrator,
        attitude=s.attitude_states,
    )
    return limits, ocp


def build_backend(model: RobotModel, settings: MpcSettings):
    """The back-end of ``settings`` in this process (what a solver worker builds)."""
    _, ocp = morphing_problem(model, settings)
    return make_backend(settings.solver, ocp, settings.options)


class InertialMorphingMpc(Closable):
    """The OCP of :mod:`.ocp` with one back-end and a shifted warm start.

    With ``settings.options.isolated`` the back-end is a
    :class:`~splitter_mpc.core.solver_worker.SolverWorker`: every solve ends within
    ``max_time_s`` of wall time whatever the solver does. A back-end bounded by
    construction (:data:`~splitter_mpc.core.solvers.BOUNDED_SOLVERS`) needs none and
    is always solved in this process. Call :meth:`close` (or use the object as a
    context manager) to stop the worker.
    """

    def __init__(
        self,
        model: RobotModel,
        settings: MpcSettings | None = None,
        *,
        lazy_backend: bool = False,
    ) -> None:
        self.model = model
        self.settings = settings or MpcSettings()
        s = self.settings
        self.limits, self.ocp = morphing_problem(model, s)
        # lazy_backend: built at the first solve, for a controller that may never solve
        # (a disabled one in the library loop: the worker's start-up is ~1 s)
        self.backend = None if lazy_backend else self._build_backend()
        self._dynamics = dynamics_function(
            s.dt_s, self.ocp.inertia_map, s.integrator, self.ocp.state
        ).expand()
        self._last: tuple[int, SolverResult] | None = None
        self.mass_model = model
        # [-] D with M_model = M_built D, and c [m^2] with M_built c = 2 J (the hemi
        # bodies' own moments): the OCP, built with the model's masses and point bodies,
        # plans in s~ = D s + c (set_mass_model)
        self.column_scale = np.ones(3)
        self.state_offset = np.zeros(3)
        self.own_inertia = np.zeros(3)  # [kg m^2] 2 J, both bodies
        # (r_min, r_max) [m] of the shapes that remain after a fault; None: the model's
        self.radius_bounds_m: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None

    def set_mass_model(
        self, model: RobotModel, hemi_inertia_kg_m2: ArrayLike = (0.0, 0.0, 0.0)
    ) -> None:
        """Plan for a robot with other masses (the same geometry) and hemi bodies with
        their own principal moments ``J`` [kg m^2] each, without rebuilding.

        Each column of the map ``I = M s`` (paper eq. 2) is one mass times a constant:
        ``m_tether = 2 m_x + 4 m_y + 4 m_z`` for ``r_x^2``, ``4 m_y`` for ``r_y^2``,
        ``4 m_z`` for ``r_z^2``. So ``M_model = M_built D`` with D diagonal, and the
        built OCP in the scaled coordinates ``s~ = D s`` is exactly the model's: the
        dynamics and costs are the built ones, and the box bounds on ``s`` and its rate
        become box bounds on ``s~`` scaled by D (:meth:`problem`). The tension row keeps
        the built ``m_x`` (the estimator keeps the nominal ``m_x``). Plans are returned
        as shapes (:attr:`MpcPlan.inertia` in the built model's moments), so the setpoints
        mean the same radii to an allocator that knows only the built model.

        The bodies' own moments add a constant ``2 J`` to every shape's inertia:
        ``I = M_model s + 2 J = M_built (D s + c)`` with ``M_built c = 2 J``. The OCP's
        states carry ``s~ = D s + c``, its dynamics are unchanged, its bounds shift by
        ``c``, the measured inertia loses ``2 J`` before its projection onto the shapes
        and the plans lose ``c`` before they become shapes. ``J = 0``: ``c = 0`` and
        every number is the point bodies' to the bit.
        """
        built = self.ocp.inertia_map
        wanted = inertia_map(model)
        scale = np.array(
            [wanted[1, 0] / built[1, 0], wanted[0, 1] / built[0, 1], wanted[0, 2] / built[0, 2]]
        )
        if not np.allclose(wanted, built * scale[None, :], rtol=1e-12, atol=0.0):
            raise ValueError("set_mass_model: the model's geometry differs from the built one")
        self.mass_model = model
        self.column_scale = scale
        self.own_inertia = 2.0 * np.asarray(hemi_inertia_kg_m2, dtype=float).reshape(3)
        self.state_offset = np.linalg.solve(built, self.own_inertia)
        s = self.settings
        self.limits = morphing_limits(model, s.dt_s, s.tension_min_n, s.radius_rate_scale)

    def set_radius_bounds(
        self, radius_min_m: ArrayLike | None, radius_max_m: ArrayLike | None
    ) -> None:
        """Plan within these radius bounds (r_x, r_y, r_z) [m] from the next solve: the
        reachable set that remains after a fault (``splitter_model.redundancy``); None:
        the model's. ValueError unless 0 < min < max, finite."""
        self.radius_bounds_m = checked_radius_bounds(radius_min_m, radius_max_m)

    @property
    def reachable(self) -> ReachableSet:
        """The reachable set planned within: the mass model's, within any fault's radius bounds."""
        base = self.limits.reachable
        if self.radius_bounds_m is None:
            return base
        lo, hi = self.radius_bounds_m
        return replace(
            base,
            radius_min_m=lo,
            radius_max_m=hi,
            inertia_min_kg_m2=base.inertia(lo**2),
            inertia_max_kg_m2=base.inertia(hi**2),
        )

    def _build_backend(self):
        s = self.settings
        if s.options.isolated and s.solver in BOUNDED_SOLVERS:
            _LOG.info("%s is bounded by construction: solved in this process", s.solver)
        elif s.options.isolated:
            return SolverWorker(
                partial(build_backend, self.model, s),
                s.options.max_time_s,
                wait_for_start=s.options.wait_for_worker_start,
            )
        return make_backend(s.solver, self.ocp, s.options)

    @property
    def horizon(self) -> int:
        return self.settings.horizon

    @property
    def deadline_misses(self) -> int:
        """Solves abandoned at their wall-time deadline (isolated back-end only)."""
        return getattr(self.backend, "deadline_misses", 0)

    def close(self) -> None:
        """Stop the solver worker, if any."""
        close_part(self.backend)

    def reset(self) -> None:
        """Forget the warm start (the next solve starts cold)."""
        self._last = None

    def rollout(self, x0: ArrayLike, controls: ArrayLike) -> NDArray[np.float64]:
        """States (len(controls)+1, nx) of the MPC model from ``x0``."""
        xs = [np.asarray(x0, dtype=float)]
        for u in np.asarray(controls, dtype=float).reshape(-1, NU):
            xs.append(np.asarray(self._dynamics(xs[-1], u), dtype=float).ravel())
        return np.array(xs)

    def _warm_start(self, t_ns: int, x0: NDArray) -> tuple[NDArray, NDArray, NDArray]:
        n, nx = self.horizon, self.ocp.state.nx
        ng = nx + NG_PATH
        shift = None
        if self._last is not None:
            last_t, last = self._last
            elapsed = t_ns - last_t
            if elapsed >= 0 and elapsed % self.settings.dt_ns == 0:
                shift = elapsed // self.settings.dt_ns
        if shift is None or shift >= n:
            xs = self.rollout(x0, np.zeros((n, NU)))
            z = self.ocp.join(xs, np.zeros((n, NU)))
            return z, np.zeros(self.ocp.n_g), np.zeros(self.ocp.n_z)
        xs, us = self.ocp.split(last.z)
        us = np.vstack([us[shift:], np.zeros((shift, NU))])
        xs = np.vstack([xs[shift:], np.zeros((shift, nx))])
        xs[0] = x0
        if shift > 0:  # roll the tail out from the last kept state
            xs[n - shift :] = self.rollout(xs[n - shift], us[n - shift :])
        lam_g = last.lam_g.reshape(n, ng)
        lam_g = np.vstack([lam_g[shift:], np.repeat(lam_g[-1:], shift, axis=0)]).ravel()
        lam_z = np.zeros(self.ocp.n_z)
        return self.ocp.join(xs, us), lam_g, lam_z

    def solve(self, request: PlanRequest) -> MpcPlan:
        """Plan from the measured state of ``request`` (:class:`PlanRequest`).

        The plan is returned whatever the solver's status; check
        ``plan.result.usable`` before executing it. The warm start is updated by
        usable solutions (and by every finite sqp/rti iterate).
        """
        t_ns = request.t_ns
        data = self.problem(request)
        bad = non_finite_fields(data)
        if bad:  # never handed to a solver (casadi#3857: fatrop can freeze on them)
            _LOG.warning("MPC problem at t = %d ns has non-finite %s: not solved", t_ns, bad)
            result = failed_result(data, STATUS_NON_FINITE_DATA, 0.0)
        else:
            if self.backend is None:
                self.backend = self._build_backend()
            result = self.backend.solve(data)
        xs, _ = self.ocp.split(result.z)
        layout = self.ocp.state
        shape = xs.copy()  # the planned radii^2, whatever masses were planned with
        shape[:, layout.radii_sq] -= self.state_offset
        shape[:, layout.radii_sq] /= self.column_scale
        if result.usable or (self.settings.solver in ("sqp", "rti") and np.isfinite(result.cost)):
            self._last = (int(t_ns), result)  # an SQP iterate still warm-starts the next one
        return MpcPlan(
            t_ns=int(t_ns),
            dt_ns=self.settings.dt_ns,
            angular_velocity=xs[:, layout.w],
            orientation=xs[:, layout.q] if layout.attitude else None,
            inertia=self.ocp.inertia_of(shape),
            radii=np.sqrt(np.maximum(shape[:, layout.radii_sq], 0.0)),
            result=result,
        )

    def problem(self, request: PlanRequest) -> ProblemInstance:
        """The NLP :meth:`solve` hands to the back-end: warm start, bounds, parameters."""
        if request.weights.tracks_attitude and not self.settings.attitude_states:
            raise ValueError(
                "weights q_q/q_tq track the attitude, but this MPC was built without it "
                "(MpcSettings.attitude_states; see settings_for_weights)"
            )
        weights = request.weights.per_stage(self.settings.weights_step_ratio)
        measured = np.asarray(request.state, dtype=float).reshape(N_MEASURED)
        x0 = self.ocp.state_from_measurement(
            measured[0:3], measured[3:7], measured[7:10] - self.own_inertia, self.reachable
        )
        scale, offset = self.column_scale, self.state_offset
        x0[self.ocp.state.radii_sq] *= scale
        x0[self.ocp.state.radii_sq] += offset
        z0, lam_g0, lam_z0 = self._warm_start(int(request.t_ns), x0)
        lbz, ubz = self.ocp.variable_bounds(x0, scale, offset, self.radius_bounds_m)
        lbg, ubg = self.ocp.constraint_bounds(x0, scale, offset)
        momentum_norm = float(np.linalg.norm(self.ocp.inertia_of(x0) * x0[0:3]))
        axis, _ = momentum_target(request.w_ref_rad_s, momentum_norm)
        lowest, highest = self.reachable.axis_inertia_range(axis)
        own = float(np.asarray(axis) ** 2 @ self.own_inertia)  # e' (2 J) e [kg m^2]
        nominal = request.nominal_inertia_kg_m2
        return ProblemInstance(
            z0=z0,
            lam_g0=lam_g0,
            lam_z0=lam_z0,
            p=parameter_vector(
                self.ocp.layout,
                request.w_ref_rad_s,
                request.q_ref_wxyz,
                weights,
                measured[7:10] if nominal is None else nominal,
                momentum_norm=momentum_norm,
                axis_inertia_range_kg_m2=(lowest + own, highest + own),
            ),
            lbz=lbz,
            ubz=ubz,
            lbg=lbg,
            ubg=ubg,
        )
