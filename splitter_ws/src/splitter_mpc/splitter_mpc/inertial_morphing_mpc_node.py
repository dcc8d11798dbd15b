"""``inertial_morphing_mpc`` node: the MPC of paper section VI on the node graph.

Thin ROS layer over :class:`splitter_mpc.core.controller.MorphingController`
(the library loop calls the same object). Lockstep (docs/ARCHITECTURE.md): once
it holds ``/splitter/imu`` and ``/splitter/inertia`` stamped with the same control
tick ``t`` it re-plans (on the 100 ms grid, or without a plan) and publishes the
setpoint for ``t`` on ``/splitter/inertia_setpoint`` stamped ``t``. The first tick
waits for the attitude reference (``/splitter/attitude_reference`` and
``/splitter/attitude_reference_pose``, latched, published by the gait phase
manager on its first tick), and for the gait phase when a node publishes one, so
that the first plan does not depend on message order (a first tick answered before
the phase arrived would plan where LAUNCH holds the nominal shape).
``/splitter/gait_phase`` (latched) switches it off in LANDED.
When a gait phase manager is in the graph (it publishes
``/splitter/jump_command``), each tick ``t`` is answered only after the manager's
jump command stamped ``t``: the manager publishes a phase or reference change of
tick ``t`` before that command, so tick ``t`` plans with the phase and reference
of tick ``t`` whatever the message timing, in the library loop's order (gait,
then MPC). Before, a phase change could reach the MPC one tick late in some runs.
``/diagnostics`` every 100 ms of simulated time: solve time, iterations,
status, cost. Bad messages are rejected with a throttled warning; the node keeps
its last good data.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, TwistStamped, Vector3Stamped, WrenchStamped
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu
from std_msgs.msg import String

from splitter_model.model import RobotModel, angular_velocity_after_morphing
from splitter_mpc.core.controller import ControllerConfig, MorphingController
from splitter_mpc.core.mpc import MpcSettings, settings_for_weights
from splitter_mpc.core.ocp import INTEGRATORS, OBJECTIVES, MpcWeights
from splitter_mpc.core.solvers import SOLVERS, SolverOptions
from splitter_msgs_py import names
from splitter_msgs_py.conversions import (
    DiagnosticStatusSample,
    MessageValidationError,
    checked_stamp_from_msg,
    diagnostics_to_msg,
    imu_from_msg,
    pose_from_msg,
    principal_inertia_from_msg,
    twist_from_msg,
    vector3_to_msg,
)
from splitter_msgs_py.core.latency import InputLatency
from splitter_msgs_py.core.stamps import StampGate
from splitter_msgs_py.node_pattern import run_node
from splitter_msgs_py.parameters import (
    InvalidParameterError,
    ParameterSpec,
    ParameterValue,
    declare_parameters,
    parameter_diagnostics,
    rejection_counts,
    warn_throttled,
)
from splitter_msgs_py.presence import PublisherPresence
from splitter_msgs_py.qos import LATCHED_QOS, qos_for
from splitter_msgs_py.signals import StopRequest

NODE_NAME = "inertial_morphing_mpc"
MAX_RATE_RAD_S = 100.0  # [rad/s] likewise for rates

PARAMETERS = (
    ParameterSpec(
        "enabled", True, "run the MPC; false holds the nominal inertia (open loop)", live=True
    ),
    ParameterSpec(
        "plan_from_setpoints",
        False,
        "real time: plan from the inertia the setpoints already sent will reach (the "
        "allocator stamps them ahead by the latency), with the body rate momentum gives "
        "there, not from the inertia measured now, which lags them",
    ),
    ParameterSpec(
        "q_w", [100.0, 100.0, 100.0], "angular velocity weights Q_w", 0.0, 1e9, length=3, live=True
    ),
    ParameterSpec(
        "r",
        [0.01, 1.0, 1.0],
        "control effort weights R (dI per step)",
        1e-9,
        1e9,
        length=3,
        live=True,
    ),
    ParameterSpec(
        "q_t",
        [100.0, 10.0, 100.0],
        "terminal angular velocity weights Q_t",
        0.0,
        1e9,
        length=3,
        live=True,
    ),
    ParameterSpec(
        "q_q",
        0.0,
        "quaternion tracking weight Q_q (live while > 0 from start-up: the attitude is then "
        "in the MPC's state)",
        0.0,
        1e9,
        live=True,
    ),
    ParameterSpec(
        "q_tq",
        0.0,
        "terminal quaternion weight Q_tq (live like q_q)",
        0.0,
        1e9,
        live=True,
    ),
    ParameterSpec(
        "tension_slack_weight",
        100.0,
        "L1 penalty of a tension shortfall [s^2/rad^2]",
        0.0,
        1e9,
        live=True,
    ),
    ParameterSpec("horizon", 50, "prediction horizon N [steps]", 2, 1000),
    ParameterSpec("dt_s", 0.01, "prediction step [s] (whole milliseconds)", 0.001, 1.0),
    ParameterSpec(
        "weights_step_s",
        0.0,
        "prediction step the weights are given for [s] (0: per stage); the stage weights "
        "then keep one continuous-time cost",
        0.0,
        1.0,
    ),
    ParameterSpec(
        "recovery_spin_rad_s",
        0.0,
        "supervisory recovery: while the body turns across the reference axis, ask the MPC "
        "for at least this spin about it [rad/s] (0: off)",
        0.0,
        100.0,
        live=True,
    ),
    ParameterSpec(
        "recovery_momentum_ratio_max",
        1.0e9,
        "recovery only for a tumble whose slowest spin about the reference axis, |H| / "
        "I_max, is under this multiple of |w_ref| [-] (1: the reference spin is reachable; "
        "1e9: any tumble)",
        1.0e-3,
        1.0e9,
        live=True,
    ),
    ParameterSpec(
        "integrator",
        "euler",
        "prediction model integrator (euler: the paper's)",
        choices=INTEGRATORS,
    ),
    ParameterSpec(
        "objective",
        "paper",
        "how q_w/q_t weigh the rate: momentum (rate across w_ref, reachable spin along it) "
        "or paper (w - w_ref)",
        choices=OBJECTIVES,
        live=True,
    ),
    ParameterSpec("replan_period_s", 0.1, "re-plan period [s]", 0.001, 10.0),
    ParameterSpec("control_period_s", 0.01, "setpoint period [s]", 0.001, 1.0),
    ParameterSpec("solver", "fatrop", "optimisation back-end", choices=SOLVERS),
    ParameterSpec("max_iter", 30, "iteration cap per solve", 1, 10000),
    ParameterSpec(
        "max_solve_time_s",
        0.08,
        "wall-time deadline per solve [s]; a missed one executes the previous plan",
        1e-3,
        60.0,
    ),
    ParameterSpec(
        "isolated_solver",
        True,
        "solve in a worker process killed at the deadline (the only bound that holds when "
        "a native solve freezes); false solves in the node's process",
    ),
    ParameterSpec(
        "wait_for_solver_start",
        True,
        "after a missed deadline, wait for the restarted worker outside the deadline "
        "(lockstep, deterministic); false counts its start against the deadline (real time)",
    ),
    ParameterSpec("tolerance", 1e-6, "solver tolerance (scaled problem)", 1e-14, 1e-2),
    ParameterSpec("compile", True, "compile the derivative code with gcc (cached on disk)"),
    ParameterSpec(
        "cache_dir", "", "compiled-code cache ('' = $SPLITTER_CACHE_DIR or ~/.cache/splitter)"
    ),
    ParameterSpec("tension_min_n", 1.0, "taut-tether margin [N]", 0.0, 1e4),
    ParameterSpec(
        "radius_rate_scale", 1.0, "share of the actuator radius speeds planned", 1e-3, 1.0
    ),
    ParameterSpec(
        "diagnostics_period_s",
        0.1,
        "diagnostics period, simulated time [s]",
        0.001,
        10.0,
        live=True,
    ),
)
# Applied to the next tick (a re-plan's weights, the recovery supervisor, on/off) without
# rebuilding the solver: the weights are parameters of the compiled NLP (core.ocp).


def controller_config_from_parameters(values: dict) -> ControllerConfig:
    """The core configuration from validated parameter values (InvalidParameterError if not)."""
    try:
        options = SolverOptions(
            max_iter=int(values["max_iter"]),
            max_time_s=float(values["max_solve_time_s"]),
            tol=float(values["tolerance"]),
            isolated=bool(values["isolated_solver"]),
            wait_for_worker_start=bool(values["wait_for_solver_start"]),
            compile=bool(values["compile"]),
            cache_dir=Path(values["cache_dir"]).expanduser() if values["cache_dir"] else None,
        )
        mpc = MpcSettings(
            horizon=int(values["horizon"]),
            dt_s=float(values["dt_s"]),
            integrator=str(values["integrator"]),
            solver=str(values["solver"]),
            options=options,
            tension_min_n=float(values["tension_min_n"]),
            radius_rate_scale=float(values["radius_rate_scale"]),
            weights_step_s=float(values["weights_step_s"]) or None,
        )
        weights = MpcWeights(
            q_w=tuple(values["q_w"]),
            r=tuple(values["r"]),
            q_t=tuple(values["q_t"]),
            q_q=float(values["q_q"]),
            q_tq=float(values["q_tq"]),
            tension_slack=float(values["tension_slack_weight"]),
            objective=str(values["objective"]),
        )
        return ControllerConfig(
            enabled=bool(values["enabled"]),
            weights=weights,
            mpc=settings_for_weights(mpc, weights),
            replan_period_s=float(values["replan_period_s"]),
            control_period_s=float(values["control_period_s"]),
            recovery_spin_rad_s=float(values["recovery_spin_rad_s"]),
            recovery_momentum_ratio_max=float(values["recovery_momentum_ratio_max"]),
        )
    except ValueError as exc:
        raise InvalidParameterError(f"parameters (horizon/dt_s/periods/solver): {exc}") from exc


def _check_frame(frame_id: str, expected: str) -> None:
    if frame_id != expected:
        raise MessageValidationError(f"header.frame_id: expected {expected!r}, got {frame_id!r}")


class InertialMorphingMpcNode(Node):
    """Answers each control tick's imu + inertia with an inertia setpoint."""

    def __init__(self, stop: StopRequest | None = None, **kwargs) -> None:
        overrides = list(kwargs.pop("parameter_overrides", None) or [])
        if not any(p.name == "use_sim_time" for p in overrides):
            overrides.append(Parameter("use_sim_time", value=True))
        super().__init__(NODE_NAME, parameter_overrides=overrides, **kwargs)
        try:
            values = declare_parameters(self, PARAMETERS, on_live_change=self._apply_live)
            config = controller_config_from_parameters(values)
        except InvalidParameterError:
            self.destroy_node()
            raise
        self.get_logger().info(
            f"building the MPC (solver {config.mpc.solver}, N = {config.mpc.horizon}, "
            f"dt = {config.mpc.dt_s} s); the first start compiles and caches its code"
        )
        self.controller = MorphingController(RobotModel(), config)
        if stop is not None and hasattr(self.controller.mpc.backend, "abandon"):
            # a stop signal ends a solve being waited for (the worker is killed)
            self.controller.mpc.backend.abandon = lambda: stop.requested
        self._control_ns = config.control_period_ns
        self._diagnostics_ns = round(float(values["diagnostics_period_s"]) * 1e9)
        self._imu: dict[int, object] = {}
        self._inertia: dict[int, np.ndarray] = {}
        self._w_ref: tuple[int, np.ndarray] | None = None
        self._q_ref: tuple[int, np.ndarray] | None = None
        self._reference_stamp: int | None = None
        self._phase: str | None = None
        self._waiting_tick: int | None = None
        self._gait_answered: int | None = None  # stamp of the last jump command [ns]
        self._last_answered: int | None = None
        self._stamps = StampGate()  # no stamp backwards per topic, none far ahead
        self._has_publisher = PublisherPresence(self)
        self.published = 0
        self._plan_from_setpoints = bool(values["plan_from_setpoints"])
        self._last_setpoint: np.ndarray | None = None  # [kg m^2] the last one sent
        self._latency = InputLatency()  # a tick's state: simulated clock when used - stamp

        self._setpoint_pub = self.create_publisher(
            Vector3Stamped, names.INERTIA_SETPOINT, qos_for(names.INERTIA_SETPOINT)
        )
        self._diagnostics_pub = self.create_publisher(
            DiagnosticArray, names.DIAGNOSTICS, qos_for(names.DIAGNOSTICS)
        )
        self.create_subscription(Imu, names.IMU, self._on_imu, qos_for(names.IMU))
        self.create_subscription(
            Vector3Stamped, names.INERTIA, self._on_inertia, qos_for(names.INERTIA)
        )
        self.create_subscription(
            TwistStamped, names.ATTITUDE_REFERENCE, self._on_w_ref, LATCHED_QOS
        )
        self.create_subscription(
            PoseStamped, names.ATTITUDE_REFERENCE_POSE, self._on_q_ref, LATCHED_QOS
        )
        self.create_subscription(String, names.GAIT_PHASE, self._on_phase, LATCHED_QOS)
        self.create_subscription(
            WrenchStamped, names.JUMP_COMMAND, self._on_gait_answer, qos_for(names.JUMP_COMMAND)
        )
        self.get_logger().info("ready")

    def _apply_live(self, values: Mapping[str, ParameterValue]) -> None:
        """A live parameter change: the controller's weights and scheduler settings.

        The solver is reused (its weights are NLP parameters): a change whose solver
        would differ (q_q or q_tq made > 0 while the MPC was built without the
        attitude in its state) is refused.
        """
        config = controller_config_from_parameters(dict(values))
        built = self.controller.config
        if config.mpc != built.mpc:
            raise InvalidParameterError(
                "q_q/q_tq > 0 needs the attitude in the MPC's state, which this MPC was built "
                "without (q_q = q_tq = 0 at start-up): restart the node with them"
            )
        diagnostics_ns = round(float(values["diagnostics_period_s"]) * 1e9)
        if diagnostics_ns % self._control_ns != 0:
            raise InvalidParameterError(
                f"diagnostics_period_s must be a multiple of control_period_s "
                f"({self._control_ns * 1e-9:g} s)"
            )
        self.controller.config = config
        self.controller.set_weights(config.weights)
        self._diagnostics_ns = diagnostics_ns

    def destroy_node(self) -> None:
        """Stop the solver worker with the node."""
        controller = getattr(self, "controller", None)
        if controller is not None:
            controller.close()
        super().destroy_node()

    # --- inputs --------------------------------------------------------------------------
    def _reject(self, topic: str, exc: Exception) -> None:
        warn_throttled(self, topic, f"rejected {topic}: {exc}; keeping the last good data")

    def _clock_ns(self) -> int | None:
        """The node's (simulated) time, None before the first /clock."""
        now = self.get_clock().now().nanoseconds
        return now if now > 0 else None

    def _checked_stamp(self, topic: str, t_ns: int) -> int:
        """``t_ns`` if in order on ``topic``, not before the last answered tick, not far ahead."""
        self._stamps.check(topic, t_ns, self._clock_ns)
        if self._last_answered is not None and t_ns < self._last_answered:
            raise MessageValidationError(
                f"header.stamp {t_ns * 1e-9:.3f} s: before the tick already answered "
                f"({self._last_answered * 1e-9:.3f} s)"
            )
        return t_ns

    def _on_imu(self, msg: Imu) -> None:
        try:
            _check_frame(msg.header.frame_id, names.BASE_FRAME)
            sample = imu_from_msg(msg)
            if np.max(np.abs(sample.angular_velocity_rad_s)) > MAX_RATE_RAD_S:
                raise MessageValidationError(
                    f"angular_velocity: |w| component above {MAX_RATE_RAD_S} rad/s"
                )
            self._checked_stamp(names.IMU, sample.t_ns)
        except MessageValidationError as exc:
            self._reject(names.IMU, exc)
            return
        self._stamps.accept(names.IMU, sample.t_ns)
        self._imu[sample.t_ns] = sample
        self._try_tick(sample.t_ns)

    def _on_inertia(self, msg: Vector3Stamped) -> None:
        try:
            sample = principal_inertia_from_msg(msg)
            self._checked_stamp(names.INERTIA, sample.t_ns)
        except MessageValidationError as exc:
            self._reject(names.INERTIA, exc)
            return
        self._stamps.accept(names.INERTIA, sample.t_ns)
        self._inertia[sample.t_ns] = sample.vector
        self._try_tick(sample.t_ns)

    def _on_w_ref(self, msg: TwistStamped) -> None:
        try:
            _check_frame(msg.header.frame_id, names.BASE_FRAME)
            linear = msg.twist.linear
            if (linear.x, linear.y, linear.z) != (0.0, 0.0, 0.0):  # NaN compares unequal too
                raise MessageValidationError("twist.linear: a rate reference has none")
            w_ref = twist_from_msg(msg)
            if np.max(np.abs(w_ref[1])) > MAX_RATE_RAD_S:
                raise MessageValidationError("twist.angular: above the rate limit")
            self._stamps.check(names.ATTITUDE_REFERENCE, w_ref[0], self._clock_ns)
        except MessageValidationError as exc:
            self._reject(names.ATTITUDE_REFERENCE, exc)
            return
        self._stamps.accept(names.ATTITUDE_REFERENCE, w_ref[0])
        self._w_ref = w_ref
        self._update_reference()

    def _on_q_ref(self, msg: PoseStamped) -> None:
        try:
            _check_frame(msg.header.frame_id, names.WORLD_FRAME)
            t_ns, q, _ = pose_from_msg(msg)
            self._stamps.check(names.ATTITUDE_REFERENCE_POSE, t_ns, self._clock_ns)
        except MessageValidationError as exc:
            self._reject(names.ATTITUDE_REFERENCE_POSE, exc)
            return
        self._stamps.accept(names.ATTITUDE_REFERENCE_POSE, t_ns)
        self._q_ref = (t_ns, q)
        self._update_reference()

    def _on_phase(self, msg: String) -> None:
        if msg.data not in names.GAIT_PHASES:
            self._reject(names.GAIT_PHASE, ValueError(f"unknown phase {msg.data!r}"))
            return
        self._phase = msg.data
        if self._waiting_tick is not None:
            tick, self._waiting_tick = self._waiting_tick, None
            self._try_tick(tick)

    def _on_gait_answer(self, msg: WrenchStamped) -> None:
        """The gait manager answered the tick of this stamp (its contents are not used)."""
        try:
            t_ns = checked_stamp_from_msg(msg.header.stamp)
            self._stamps.check(names.JUMP_COMMAND, t_ns, self._clock_ns)
        except MessageValidationError as exc:
            self._reject(names.JUMP_COMMAND, exc)
            return
        self._stamps.accept(names.JUMP_COMMAND, t_ns)
        self._gait_answered = t_ns
        if self._waiting_tick is not None and self._waiting_tick <= t_ns:
            tick, self._waiting_tick = self._waiting_tick, None
            self._try_tick(tick)

    def _waits_for_gait(self, t_ns: int) -> bool:
        """True while a gait manager is in the graph and has not answered tick ``t_ns``."""
        if self._gait_answered is not None and self._gait_answered >= t_ns:
            return False
        return self._has_publisher(names.JUMP_COMMAND)

    def _update_reference(self) -> None:
        if self._w_ref is None or self._q_ref is None:
            return
        stamp = self._q_ref[0]
        try:
            self.controller.set_reference(stamp, self._w_ref[1], self._q_ref[1])
        except ValueError as exc:
            self._reject(names.ATTITUDE_REFERENCE_POSE, exc)
            return
        self._reference_stamp = stamp
        if self._waiting_tick is not None:
            tick, self._waiting_tick = self._waiting_tick, None
            self._try_tick(tick)

    # --- the tick ------------------------------------------------------------------------
    def _try_tick(self, t_ns: int) -> None:
        if t_ns % self._control_ns != 0 or t_ns == self._last_answered:
            self._drop_before(t_ns)
            return
        if t_ns not in self._imu or t_ns not in self._inertia:
            return
        if self.controller.config.enabled and (
            self.controller.reference is None
            or (self._phase is None and self._has_publisher(names.GAIT_PHASE))
            or self._waits_for_gait(t_ns)
        ):
            # answered when the first reference and phase and the gait's answer arrive
            self._waiting_tick = t_ns
            return
        imu = self._imu[t_ns]
        inertia = self._inertia[t_ns]
        self._latency.record("state", t_ns, self._clock_ns())
        w = imu.angular_velocity_rad_s
        if self._plan_from_setpoints and self._last_setpoint is not None:
            # the commands stamped ahead reach the last setpoint before this tick's does
            w = angular_velocity_after_morphing(w, inertia, self._last_setpoint)
            inertia = self._last_setpoint
        try:
            setpoint = self.controller.on_state(t_ns, w, imu.orientation_wxyz, inertia, self._phase)
        except ValueError as exc:  # inputs checked above; keep running regardless
            self._reject("state", exc)
            return
        self._setpoint_pub.publish(vector3_to_msg(t_ns, setpoint, names.BASE_FRAME))
        self._last_setpoint = np.asarray(setpoint, dtype=float).copy()
        self.published += 1
        self._last_answered = t_ns
        self._drop_before(t_ns + 1)
        if t_ns % self._diagnostics_ns == 0:
            self._publish_diagnostics(t_ns)

    def _drop_before(self, t_ns: int) -> None:
        for buffer in (self._imu, self._inertia):
            for stamp in [s for s in buffer if s < t_ns - self._control_ns]:
                del buffer[stamp]

    def _publish_diagnostics(self, t_ns: int) -> None:
        s = self.controller.status
        level = 0
        message = s.solve_status
        if not s.active:
            message = "inactive: holding the nominal inertia"
        elif s.consecutive_failures > 0:
            level = 1 if s.consecutive_failures < 5 else 2
            message = f"{s.solve_status}: executing the previous plan"
        values = {
            "active": s.active,
            "phase": s.phase,
            "solver": s.solver,
            "solve_status": s.solve_status,
            "solve_ok": s.solve_ok,
            "converged": s.converged,
            "iterations": s.iterations,
            "solve_time_ms": s.solve_time_ms,
            "cost": s.cost,
            "infeasibility": s.infeasibility,
            "plan_age_s": s.plan_age_s,
            "solves": s.solves,
            "failures": s.failures,
            "deadline_misses": s.deadline_misses,
            "consecutive_failures": s.consecutive_failures,
            "recovering": s.recovering,
            "setpoint_ixx_kg_m2": s.setpoint_kg_m2[0],
            "setpoint_iyy_kg_m2": s.setpoint_kg_m2[1],
            "setpoint_izz_kg_m2": s.setpoint_kg_m2[2],
            "rejected_messages": sum(rejection_counts(self).values()),
            **self._latency.values(),
            **parameter_diagnostics(self),
        }
        values = {
            k: v for k, v in values.items() if not (isinstance(v, float) and not np.isfinite(v))
        }
        status = DiagnosticStatusSample(f"{NODE_NAME}: inertia setpoint", level, message, values)
        try:
            self._diagnostics_pub.publish(diagnostics_to_msg(t_ns, [status]))
        except MessageValidationError as exc:
            self.get_logger().error(f"diagnostics not published: {exc}")


def main(args: list[str] | None = None) -> int:
    """Run the node until Ctrl-C or shutdown; an invalid parameter stops it with exit code 1."""
    return run_node(lambda stop: InertialMorphingMpcNode(stop=stop), NODE_NAME, args)


if __name__ == "__main__":
    raise SystemExit(main())
