"""The MPC scheduler shared by the ``inertial_morphing_mpc`` node and the library loop.

:meth:`MorphingController.on_state` is called once per control tick (100 Hz) with
the measured state stamped on that tick; it re-plans on the re-plan grid
(10 Hz, paper Table I) or when it has no plan, and returns the inertia setpoint
for the tick from the current plan (docs/ARCHITECTURE.md, lockstep step 3).

* Active in the airborne phases (IN_FLIGHT, LANDING; docs/ARCHITECTURE.md,
  "Gait phases and the MPC"), once an attitude reference has been set, until the
  gait hands the limbs back to the legs (``stance_shape``: the predicted touchdown
  is within its lead, or the robot is on the ground). LANDED, it
  holds its last setpoint (the robot keeps the shape it landed in). On the ground
  before a jump (LAUNCH, JUMP), before a reference, or disabled (open loop), it
  holds the nominal inertia: the configured one, else the first inertia it
  measured (the legs stand and push in the nominal shape).
* A failed or late solve (solver error, non-finite problem data or result,
  infeasible result, wall-time deadline ``SolverOptions.max_time_s`` missed: the
  solver worker is killed and restarted, :mod:`.solver_worker`; injected failure) keeps the previous
  plan: its later steps are played back on the following ticks, the failure is
  counted and reported, and the next re-plan tries again. Without any plan it
  holds the measured inertia.
* It never returns a non-finite setpoint.

ROS-free and deterministic (the solvers are deterministic; a wall-time deadline
that is missed is counted in ``ControllerStatus.deadline_misses``).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.model import (
    InfeasibleInertiaError,
    RobotModel,
    principal_inertia,
    radii_from_inertia,
)
from splitter_mpc.core.gait import AttitudeReference, GaitPhase, propagate_attitude
from splitter_mpc.core.mpc import (
    NS_PER_S,
    InertialMorphingMpc,
    MpcPlan,
    MpcSettings,
    PlanRequest,
    checked_radius_bounds,
)
from splitter_mpc.core.ocp import MpcWeights
from splitter_mpc.core.solvers import Closable, close_part
from splitter_msgs_py.core.parameter_fields import PERIOD_S, parameter_field

_LOG = logging.getLogger(__name__)
# Inactive phases: on the ground (LAUNCH, JUMP) the limbs are legs and stand in the
# nominal shape (their stroke is what the jump and the touchdown use); LANDED keeps
# the shape it landed in.
INACTIVE_PHASES = (GaitPhase.LAUNCH.value, GaitPhase.JUMP.value, GaitPhase.LANDED.value)


@dataclass(frozen=True)
class ControllerConfig:
    """Scheduler settings (paper Table I: re-plan every 0.1 s, setpoints every 0.01 s)."""

    enabled: bool = parameter_field(
        True, "run the MPC; false holds the nominal inertia (open loop)", live=True
    )
    weights: MpcWeights = field(default_factory=MpcWeights)
    mpc: MpcSettings = field(default_factory=MpcSettings)
    replan_period_s: float = parameter_field(  # [s]
        0.1, "re-plan period [s]", bounds=PERIOD_S
    )
    control_period_s: float = parameter_field(  # [s]
        0.01, "setpoint period [s]", bounds=(0.001, 1.0)
    )
    nominal_inertia_kg_m2: tuple[float, float, float] | None = None  # held when inactive
    # The actuators follow a first-order lag of this time constant (the robot's servos,
    # splitter_model.actuators.CommandLag): a smooth command arrives about that late, so
    # each setpoint is the plan's value this much ahead of its tick.
    actuator_lag_s: float = parameter_field(  # [s]
        0.0,
        "the actuators' first-order lag time constant: each setpoint is taken this far "
        "ahead on the plan, so the lagging shape follows the plan on time [s] (0: none)",
        bounds=(0.0, 1.0),
    )
    # The commands reach the actuators this late (transport and servo bus): a pure delay,
    # added to the lead.
    command_latency_s: float = parameter_field(  # [s]
        0.0,
        "the commands' latency to the actuators: each setpoint is taken this much further "
        "ahead on the plan [s] (0: none)",
        bounds=(0.0, 1.0),
    )
    # Recovery (supervisory): while the body rate across the reference axis is above
    # ``recovery_enter_rate_rad_s``, the MPC is asked for a spin of at least
    # ``recovery_spin_rad_s`` about that axis (0: off), until that rate falls under
    # ``recovery_exit_rate_rad_s``; then for the reference again. A tumble is turned
    # into a spin about the axis about as fast as that spin turns (README, "Random
    # tumbles"): a faster spin recovers faster, and the tether is reeled in for it.
    recovery_spin_rad_s: float = parameter_field(  # [rad/s]
        0.0,
        "supervisory recovery: while the body turns across the reference axis, ask the MPC "
        "for at least this spin about it [rad/s] (0: off)",
        bounds=(0.0, 100.0),
        live=True,
    )
    recovery_enter_rate_rad_s: float = 0.05  # [rad/s]
    recovery_exit_rate_rad_s: float = 0.005  # [rad/s]
    # [-] recovery only for a tumble with too little momentum to exceed this multiple
    # of the reference spin even at the largest inertia about the axis:
    # ``|H| / I_e,max < ratio * |w_ref|``. At 1 the reference spin is reachable (a slow
    # tumble, whose turn is slow: its rates scale with |H|); a tumble with more
    # momentum (the paper's Table I: |H| / I_e,max = 1.10 rad/s) ends faster than the
    # reference anyway and is left to the MPC. 1e9 (or inf): any tumble.
    recovery_momentum_ratio_max: float = parameter_field(
        1.0e9,
        "recovery only for a tumble whose slowest spin about the reference axis, |H| / "
        "I_max, is under this multiple of |w_ref| [-] (1: the reference spin is reachable; "
        "1e9: any tumble)",
        bounds=(1.0e-3, 1.0e9),
        live=True,
    )

    # After a fault (radius bounds from the allocator's /splitter/joint_health) the
    # effort weights R are scaled by this: with a limb pair held the residual nutation
    # is damped within a narrower reachable set, and the paper's R (tuned with every
    # joint working) leaves it settling past 20 s. Seed 0's 18 limp hip pitch draws:
    # 1/18 stabilized at 1, 8/18 at 0.1, 14/18 at 0.01; its 27 locked knees 26/27 at
    # 0.01 (README "A limb or the reel fails"). Healthy flights never see it.
    fault_effort_scale: float = parameter_field(
        0.01,
        "after a fault, the effort weights R are multiplied by this [-] (1: unchanged)",
        bounds=(1.0e-3, 1.0),
        live=True,
    )

    def __post_init__(self) -> None:
        scale = self.fault_effort_scale
        if not (isinstance(scale, int | float) and 1.0e-3 <= scale <= 1.0):
            raise ValueError(f"fault_effort_scale must be in [0.001, 1], got {scale!r}")
        for name in ("replan_period_s", "control_period_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be finite and > 0, got {value!r}")
        for name in ("actuator_lag_s", "command_latency_s"):
            lag = getattr(self, name)
            if not (isinstance(lag, int | float) and math.isfinite(lag) and 0.0 <= lag <= 1.0):
                raise ValueError(f"{name} must be in [0, 1] s, got {lag!r}")
        recovery = ("recovery_spin_rad_s", "recovery_enter_rate_rad_s", "recovery_exit_rate_rad_s")
        for name in recovery:
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} must be finite and >= 0, got {value!r}")
        ratio = self.recovery_momentum_ratio_max
        if not (isinstance(ratio, int | float) and not math.isnan(ratio) and ratio > 0.0):
            raise ValueError(f"recovery_momentum_ratio_max must be > 0, got {ratio!r}")
        if self.recovery_exit_rate_rad_s > self.recovery_enter_rate_rad_s:
            raise ValueError(
                "recovery_exit_rate_rad_s must be <= recovery_enter_rate_rad_s, got "
                f"{self.recovery_exit_rate_rad_s} > {self.recovery_enter_rate_rad_s}"
            )
        replan, tick = self.replan_period_ns, self.control_period_ns
        if replan % tick != 0 or replan % self.mpc.dt_ns != 0:
            raise ValueError(
                "replan_period_s must be a multiple of control_period_s and of the prediction "
                f"step (warm-start shift) (got {replan}, {tick}, {self.mpc.dt_ns} ns)"
            )
        if self.weights.tracks_attitude and not self.mpc.attitude_states:
            raise ValueError(
                "weights q_q/q_tq track the attitude: the MPC needs attitude_states "
                "(splitter_mpc.core.mpc.settings_for_weights)"
            )
        if self.nominal_inertia_kg_m2 is not None:
            nominal = np.asarray(self.nominal_inertia_kg_m2, dtype=float)
            if nominal.shape != (3,) or not np.all(np.isfinite(nominal) & (nominal > 0.0)):
                raise ValueError(f"nominal_inertia_kg_m2 must be 3 positive numbers, got {nominal}")

    @property
    def setpoint_lead_ns(self) -> int:
        """[ns] how far ahead of its tick each setpoint is taken on the plan: the
        actuators' lag and the commands' latency."""
        return round((self.actuator_lag_s + self.command_latency_s) * NS_PER_S)

    @property
    def replan_period_ns(self) -> int:
        return round(self.replan_period_s * NS_PER_S)

    @property
    def control_period_ns(self) -> int:
        return round(self.control_period_s * NS_PER_S)


@dataclass(frozen=True)
class ControllerStatus:
    """What the last tick did (the node publishes it on /diagnostics)."""

    t_ns: int = 0
    active: bool = False
    phase: str = ""
    replanned: bool = False  # this tick solved
    solver: str = ""
    solve_status: str = "none"
    solve_ok: bool = False  # the last solve's plan was accepted
    converged: bool = False
    iterations: int = 0
    solve_time_ms: float = 0.0  # [ms] wall, last solve
    cost: float = math.nan
    infeasibility: float = math.nan
    plan_age_s: float = math.nan  # [s] since the executed plan was made
    solves: int = 0
    failures: int = 0
    deadline_misses: int = 0  # solves abandoned at their wall-time deadline
    consecutive_failures: int = 0
    recovering: bool = False  # the MPC is asked for the recovery spin (ControllerConfig)
    setpoint_kg_m2: tuple[float, float, float] = (math.nan, math.nan, math.nan)


def _finite_vector(value: ArrayLike, size: int, name: str) -> NDArray[np.float64]:
    arr = np.asarray(value, dtype=float).reshape(-1)
    if arr.shape != (size,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: expected {size} finite numbers, got {value!r}")
    return arr


class MorphingController(Closable):
    """Re-plans on the re-plan grid, plays the plan back every control tick."""

    def __init__(
        self,
        model: RobotModel,
        config: ControllerConfig | None = None,
        mpc: InertialMorphingMpc | None = None,
    ) -> None:
        self.model = model
        self.config = config or ControllerConfig()
        self.mpc = mpc or InertialMorphingMpc(model, self.config.mpc)
        self.weights = self.config.weights
        self._reference: AttitudeReference | None = None
        self._plan: MpcPlan | None = None
        self._nominal: NDArray[np.float64] | None = (
            None
            if self.config.nominal_inertia_kg_m2 is None
            else np.asarray(self.config.nominal_inertia_kg_m2, dtype=float)
        )
        self._last_setpoint: NDArray[np.float64] | None = None
        # (stamp, r_min, r_max) radius bounds a fault left, used from the ticks after them
        self._pending_bounds: list[tuple] = []
        self._fault_bounds = False  # planning within bounds a fault left
        self._stance_limbs_m: NDArray[np.float64] | None = None  # [m] r_y, r_z of the legs
        self._stance_radius_x_m: float | None = None  # [m] the tether held in stance shape
        self._recovering = False
        self._failures_to_inject = 0
        self._status = ControllerStatus(solver=self.mpc.settings.solver)
        self.last_plan_result = None

    # --- inputs --------------------------------------------------------------------------
    @property
    def reference(self) -> AttitudeReference | None:
        return self._reference

    def set_reference(self, stamp_ns: int, w_ref_rad_s: ArrayLike, q_ref_wxyz: ArrayLike) -> None:
        """Angular velocity reference and the attitude reference at ``stamp_ns``.

        The attitude reference is propagated with ``w_ref`` (body frame) from its
        stamp, as the graph's ``/splitter/attitude_reference_pose`` defines it.
        """
        w_ref = _finite_vector(w_ref_rad_s, 3, "w_ref_rad_s")
        q = _finite_vector(q_ref_wxyz, 4, "q_ref_wxyz")
        norm = float(np.linalg.norm(q))
        if norm < 0.5:
            raise ValueError(f"q_ref_wxyz: not a quaternion (|q| = {norm})")
        self._reference = AttitudeReference(
            stamp_ns=int(stamp_ns), w_ref_rad_s=w_ref, q_ref_wxyz=q / norm, propagate=True
        )

    def set_weights(self, weights: MpcWeights) -> None:
        """Weights for the following solves (the built problem is reused)."""
        self.weights = weights

    def planning_weights(self) -> MpcWeights:
        """The weights of the next solve: :attr:`weights`, their R scaled by
        ``fault_effort_scale`` while planning within bounds a fault left."""
        scale = self.config.fault_effort_scale
        if not self._fault_bounds or scale == 1.0:
            return self.weights
        return replace(self.weights, r=tuple(float(r) * scale for r in self.weights.r))

    def set_mass_model(
        self, model: RobotModel, hemi_inertia_kg_m2: ArrayLike = (0.0, 0.0, 0.0)
    ) -> None:
        """Plan with these masses and hemi bodies' own moments [kg m^2] from the next
        solve (an estimate; same geometry)."""
        self.mpc.set_mass_model(model, hemi_inertia_kg_m2)

    def set_radius_bounds(
        self,
        radius_min_m: ArrayLike | None,
        radius_max_m: ArrayLike | None,
        stamp_ns: int | None = None,
    ) -> None:
        """Plan within the radius bounds [m] a fault left (``splitter_model.redundancy``);
        None: the model's. ``stamp_ns``: found then, so used from the second control tick
        after it on (:meth:`_apply_pending_bounds`).
        Raises ``ValueError`` for bounds that are not finite with 0 < min < max."""
        bounds = checked_radius_bounds(radius_min_m, radius_max_m) or (None, None)
        if stamp_ns is None:
            self.mpc.set_radius_bounds(*bounds)
            self._fault_bounds = bounds[0] is not None
            self._pending_bounds.clear()
        else:
            self._pending_bounds.append((int(stamp_ns), *bounds))

    def _apply_pending_bounds(self, t_ns: int) -> None:
        """The latest radius bounds stamped at the previous control tick or before.

        In lockstep everything stamped then has arrived: the allocator published it while
        answering that tick, before the simulator stepped on; what is stamped later may
        still be on its way (a graph and the library loop would differ).
        """
        cutoff = t_ns - self.config.control_period_ns
        due = [b for b in self._pending_bounds if b[0] <= cutoff]
        if due:
            _, low, high = max(due, key=lambda b: b[0])
            self.mpc.set_radius_bounds(low, high)
            self._fault_bounds = low is not None
            self._pending_bounds = [b for b in self._pending_bounds if b[0] > cutoff]

    def inject_solver_failures(self, count: int = 1) -> None:
        """Treat the next ``count`` solves as failed (tests of the failure handling)."""
        self._failures_to_inject += int(count)

    def close(self) -> None:
        """Stop the MPC's solver worker (if any; the Opti baseline has none)."""
        close_part(self.mpc)

    @property
    def status(self) -> ControllerStatus:
        return self._status

    @property
    def plan(self) -> MpcPlan | None:
        """The plan being executed."""
        return self._plan

    # --- the tick ------------------------------------------------------------------------
    def attitude_references(self, t_ns: int) -> NDArray[np.float64]:
        """(N+1, 4) attitude reference along the horizon from ``t_ns``."""
        ref = self._reference
        n, dt = self.mpc.horizon, self.mpc.settings.dt_s
        start = propagate_attitude(ref.q_ref_wxyz, ref.w_ref_rad_s, (t_ns - ref.stamp_ns) / 1e9)
        return np.array([propagate_attitude(start, ref.w_ref_rad_s, k * dt) for k in range(n + 1)])

    def on_state(
        self,
        t_ns: int,
        angular_velocity_rad_s: ArrayLike,
        orientation_wxyz: ArrayLike,
        inertia_kg_m2: ArrayLike,
        phase: str | None = None,
        *,
        stance_shape: bool = False,
    ) -> NDArray[np.float64]:
        """Inertia setpoint [kg m^2] for tick ``t_ns`` from the state measured at ``t_ns``.

        ``phase`` is the gait phase name (None: unknown, treated as active).
        ``stance_shape``: the limbs are legs (on the ground, or the touchdown the gait
        predicts is within its lead): the controller hands the limbs back in their
        nominal shape and holds the tether as it is (:meth:`_stance_setpoint`), so the
        robot meets the ground on its legs with the spin it slowed, and stands and
        pushes its next jump in that shape.
        Raises ``ValueError`` for non-finite or malformed inputs (state unchanged).
        """
        t_ns = int(t_ns)
        w = _finite_vector(angular_velocity_rad_s, 3, "angular_velocity_rad_s")
        q = _finite_vector(orientation_wxyz, 4, "orientation_wxyz")
        inertia = _finite_vector(inertia_kg_m2, 3, "inertia_kg_m2")
        self._apply_pending_bounds(t_ns)
        if np.linalg.norm(q) < 0.5:
            raise ValueError(f"orientation_wxyz: not a quaternion, got {q.tolist()}")
        if np.any(inertia <= 0.0):
            raise ValueError(f"inertia_kg_m2 must be > 0, got {inertia.tolist()}")
        q = q / np.linalg.norm(q)
        if self._nominal is None:
            self._nominal = inertia.copy()
        active = (
            self.config.enabled
            and self._reference is not None
            and (phase is None or phase not in INACTIVE_PHASES)
            and not stance_shape
        )
        status = {
            "t_ns": t_ns,
            "active": active,
            "phase": phase or "",
            "replanned": False,
        }
        if not active:
            if self._plan is not None:
                self.mpc.reset()
            self._plan = None
            landed = self.config.enabled and phase == GaitPhase.LANDED.value
            airborne = phase is None or phase not in INACTIVE_PHASES
            if landed and self._last_setpoint is not None:
                setpoint = self._last_setpoint.copy()  # landed: keep the shape it landed in
            elif self.config.enabled and (stance_shape or not airborne):
                setpoint = self._stance_setpoint(inertia)
            else:
                setpoint = self._nominal.copy()
        else:
            self._stance_radius_x_m = None
            if self._plan is None or t_ns % self.config.replan_period_ns == 0:
                self._update_recovery(w, inertia)
                status.update(self._replan(t_ns, np.concatenate([w, q, inertia])))
            setpoint = (
                inertia.copy()
                if self._plan is None
                else self._plan.setpoint_at(
                    t_ns + self.config.setpoint_lead_ns, self.config.control_period_ns
                )
            )
        if not np.all(np.isfinite(setpoint)):
            _LOG.error("non-finite setpoint %s at t = %d ns: holding", setpoint, t_ns)
            setpoint = self._last_setpoint if self._last_setpoint is not None else inertia.copy()
        self._last_setpoint = setpoint.copy()
        plan_age = math.nan if self._plan is None else (t_ns - self._plan.t_ns) / NS_PER_S
        self._status = ControllerStatus(
            **{
                **self._status.__dict__,
                **status,
                "plan_age_s": plan_age,
                "recovering": self._recovering and active,
                "setpoint_kg_m2": tuple(float(v) for v in setpoint),
            }
        )
        return setpoint

    def _stance_setpoint(self, inertia: NDArray[np.float64]) -> NDArray[np.float64]:
        """The nominal limbs with the tether held where it was measured [kg m^2].

        Used from the hand-back before a touchdown, on the ground, and until the MPC
        flies again. In the allocator's terms, which turn the setpoint into joints: radii
        from the moments with the controller's nominal masses (the paper's closed form),
        ``r_x`` measured on the first tick in stance shape, clipped to the tether's
        range, and held (a tether reeled back to its nominal length on the ground kept
        its reel-in speed after lift-off, which a slow spin cannot brake: the hemis
        coasted inwards and spun the robot up from 0.05 to 0.38 rad/s for the next
        landing; a setpoint that followed the measured length kept a moving reel
        moving), ``r_y`` and ``r_z`` of the nominal shape (the first measured inertia:
        the legs' stance), back to moments.
        (With the MPC's estimated masses instead, a tether near its end asked the
        allocator for more than 3.0 m, and its projection kept the limbs out.) A
        measurement the closed form refuses gives the nominal inertia.
        """
        model = self.model
        nominal = self._nominal
        assert nominal is not None
        try:
            if self._stance_limbs_m is None:
                self._stance_limbs_m = radii_from_inertia(model, nominal)[1:]
            if self._stance_radius_x_m is None:
                radius_x = float(radii_from_inertia(model, inertia)[0])
                radius_x = min(max(radius_x, model.radius_x_min_m), model.radius_x_max_m)
                self._stance_radius_x_m = radius_x
        except InfeasibleInertiaError as exc:
            _LOG.warning("stance shape from the nominal inertia: %s", exc)
            return nominal.copy()
        return principal_inertia(model, (self._stance_radius_x_m, *self._stance_limbs_m))

    def _update_recovery(self, w: NDArray[np.float64], inertia: NDArray[np.float64]) -> None:
        """Enter or leave recovery from the body rate across the reference axis."""
        c = self.config
        w_ref = np.asarray(self._reference.w_ref_rad_s, dtype=float)
        speed = float(np.linalg.norm(w_ref))
        if c.recovery_spin_rad_s <= 0.0 or speed < 1e-9:
            self._recovering = False
            return
        axis = w_ref / speed
        across = float(np.linalg.norm(w - axis * float(axis @ w)))
        if self._recovering and across < c.recovery_exit_rate_rad_s:
            self._recovering = False
            _LOG.debug("recovered: %.4f rad/s across the reference axis", across)
        elif (
            not self._recovering
            and across > c.recovery_enter_rate_rad_s
            and self.slowest_spin_rad_s(w, inertia) < c.recovery_momentum_ratio_max * speed
        ):
            self._recovering = True
            _LOG.debug("recovering: %.3f rad/s across the reference axis", across)

    def slowest_spin_rad_s(self, w: ArrayLike, inertia_kg_m2: ArrayLike) -> float:
        """|H| / I_e,max [rad/s]: the slowest spin about the reference axis this momentum gives.

        ``|H| = |I w|`` (principal body frame); ``I_e,max`` is the largest moment about
        the axis the limits reach. NaN without a reference axis.
        """
        if self._reference is None:
            return math.nan
        w_ref = np.asarray(self._reference.w_ref_rad_s, dtype=float)
        speed = float(np.linalg.norm(w_ref))
        if speed < 1e-9:
            return math.nan
        momentum = float(np.linalg.norm(np.asarray(inertia_kg_m2) * np.asarray(w)))
        _, largest = self.mpc.reachable.axis_inertia_range(w_ref / speed)
        return momentum / largest

    def spin_reference(self) -> NDArray[np.float64]:
        """The w_ref the MPC is given: the reference's, or its axis at the recovery spin."""
        w_ref = np.asarray(self._reference.w_ref_rad_s, dtype=float)
        speed = float(np.linalg.norm(w_ref))
        if not self._recovering or speed >= self.config.recovery_spin_rad_s:
            return w_ref
        return w_ref * (self.config.recovery_spin_rad_s / speed)

    def _replan(self, t_ns: int, state: NDArray[np.float64]) -> dict:
        previous = self._status
        try:
            request = PlanRequest(
                t_ns,
                state,
                self.spin_reference(),
                self.attitude_references(t_ns),
                self.planning_weights(),
                nominal_inertia_kg_m2=self._nominal,
            )
            plan = self.mpc.solve(request)
            result = plan.result
            status, ok = result.status, result.usable
            late_s = self.mpc.settings.options.max_time_s
            if ok and result.solve_time_s > late_s:  # fatrop has no wall-time cap of its own
                status, ok = (
                    f"late ({result.solve_time_s * 1e3:.0f} ms > {late_s * 1e3:.0f})",
                    False,
                )
            if self._failures_to_inject > 0:
                self._failures_to_inject -= 1
                status, ok = "injected_failure", False
            fields = {
                "solve_status": status,
                "converged": result.converged and ok,
                "iterations": result.iterations,
                "solve_time_ms": result.solve_time_s * 1e3,
                "cost": result.cost,
                "infeasibility": result.infeasibility,
            }
        except (RuntimeError, ValueError) as exc:  # a solver exception is a failed solve
            _LOG.warning("MPC solve failed at t = %d ns: %s", t_ns, exc)
            plan, ok = None, False
            fields = {"solve_status": f"error: {exc}"[:120], "converged": False}
        if ok:
            self._plan = plan
            consecutive = 0
        else:
            if previous.consecutive_failures == 0:
                _LOG.warning(
                    "MPC solve at t = %.3f s not usable (%s): executing the previous plan",
                    t_ns / NS_PER_S,
                    fields["solve_status"],
                )
            consecutive = previous.consecutive_failures + 1
        return {
            **fields,
            "replanned": True,
            "solve_ok": ok,
            "solves": previous.solves + 1,
            "failures": previous.failures + (0 if ok else 1),
            "deadline_misses": getattr(self.mpc, "deadline_misses", 0),
            "consecutive_failures": consecutive,
        }
