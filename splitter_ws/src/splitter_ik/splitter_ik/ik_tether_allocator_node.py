"""``ik_tether_allocator``: principal-inertia setpoints to joint commands, as a ROS 2 node.

A thin layer over :class:`splitter_ik.core.allocator.TetherLimbAllocator`.

* ``/splitter/inertia_setpoint`` (Vector3Stamped, Ixx Iyy Izz [kg m^2]) stamped ``t``
  is answered with ``/splitter/joint_commands`` (JointState, 25 positions and
  velocities) stamped ``t`` (docs/ARCHITECTURE.md, lockstep protocol item 4): a point
  of a piecewise-linear reference, the position planned at ``t`` and the velocity
  held until the next tick (:class:`~splitter_ik.core.allocator.Allocation`).
* ``/splitter/imu`` gives the body angular velocity for the taut-tether limit.
* ``/splitter/inertia`` (the measured state): the first one sets the starting radii
  (``initialize_from_measured_inertia``); and while nothing publishes setpoints, each
  control tick of it is answered from the last good setpoint, so that a lockstep
  simulator keeps running without the MPC (with the IMU of the same tick when an
  IMU publisher exists).
* ``/diagnostics`` once per ``diagnostics_period_s`` of simulated time (the stamps
  of the ticks answered): saturation, rate limiting, tension and its margin,
  rejected and projected setpoints.

Bad input never raises out of a callback and never resets the allocator; every
rejection is a throttled warning, counted (``rejection_counts``) and reported on
``/diagnostics``:

* a stamp that is negative, earlier than the last one of its topic (for a setpoint,
  also earlier than the last tick answered: a stamp of 0 once time has advanced is
  no "restart"), or more than ``MAX_STAMP_LEAD_NS`` ahead of the node's time (its
  simulated clock, or the newest stamp it accepted): the message is dropped,
  nothing is answered or changed;
* a setpoint stamped well but with NaN / infinite values, a moment not in
  ``(0, max_setpoint_kg_m2]`` (``SETPOINT_LIMIT_FACTOR`` times the largest reachable
  moment of the model) or a frame other than ``base``: its tick is answered from
  the last good setpoint;
* an IMU with a bad quaternion, non-finite values, a body rate above
  ``MAX_BODY_RATE_RAD_S`` or a frame other than ``base``; a measured inertia that is
  not ``base``-framed moments in ``(0, 1e4]`` kg m^2: the last good one is kept.

A reachable-set miss is not an error: the setpoint is projected onto the reachable
set (throttled warning). Invalid parameters stop the node at start-up with a
message naming the parameter. Runs on simulated time unless ``use_sim_time`` is
overridden.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu, JointState

from splitter_ik.core.allocator import Allocation, AllocatorConfig, TetherLimbAllocator
from splitter_ik.core.command_lead import CommandLead
from splitter_ik.core.projection import project_inertia, reachable_inertia_bounds
from splitter_model.actuators import TETHER_INDEX
from splitter_model.model import (
    PAPER_INITIAL_RADII_M,
    RobotModel,
    angular_velocity_after_morphing,
    principal_inertia,
)
from splitter_msgs_py import names
from splitter_msgs_py.conversions import (
    DiagnosticStatusSample,
    MessageValidationError,
    checked_stamp_from_msg,
    diagnostics_to_msg,
    imu_from_msg,
    joint_state_to_msg,
    principal_inertia_from_msg,
    vector3_from_msg,
)
from splitter_msgs_py.core.latency import InputLatency
from splitter_msgs_py.core.stamps import MAX_STAMP_LEAD_NS, StampGate
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
from splitter_msgs_py.qos import qos_for

NODE_NAME = "ik_tether_allocator"
STATUS_NAME = f"{NODE_NAME}: allocation"
# [-] a setpoint moment above this many times the largest reachable moment of the model
# (163 kg m^2 for the paper's robot) is corrupt, not merely unreachable: rejected.
SETPOINT_LIMIT_FACTOR = 10.0
# [rad/s] an IMU body rate above this is corrupt (the robot spins at ~1 rad/s, its
# joints at 84 rad/s; a gyro saturates far below): rejected.
MAX_BODY_RATE_RAD_S = 1.0e3
LEAD_HISTORY_NS = 1_000_000_000  # [ns] planned inertia kept for the rate prediction

PARAMETERS = (
    ParameterSpec(
        "control_period_s",
        0.01,
        "control tick: one command per setpoint, joint velocities over this period [s]",
        min_value=1e-4,
        max_value=10.0,
    ),
    ParameterSpec(
        "tension_margin_n",
        1.0,
        "least tether tension kept while reeling (the tether only pulls) [N]",
        min_value=1e-6,
        max_value=1e4,
        live=True,
    ),
    ParameterSpec(
        "low_spin_tension_fraction",
        0.5,
        "share of the centripetal tether load kept as tension when the load is under "
        "tension_margin_n (slow spin across the tether) [-]",
        min_value=1e-3,
        max_value=1.0,
        live=True,
    ),
    ParameterSpec(
        "reference_velocity_window_s",
        AllocatorConfig.reference_velocity_window_s,
        "the reel follows the setpoints' mean velocity over this window (one MPC re-plan "
        "period), braking taut; 0: each setpoint approached as a resting target [s]",
        min_value=0.0,
        max_value=10.0,
        live=True,
    ),
    ParameterSpec(
        "speed_fraction",
        1.0,
        "share of the actuator speed limits (800 RPM joints, tether reel) used [-]",
        min_value=1e-3,
        max_value=1.0,
    ),
    ParameterSpec(
        "limb_acceleration_fraction",
        AllocatorConfig.limb_acceleration_fraction,
        "share of the joint acceleration limit (143 rad/s^2) commanded; the rest is servo "
        "headroom that keeps hip and knee in step [-]",
        min_value=1e-3,
        max_value=1.0,
    ),
    ParameterSpec(
        "tether_acceleration_fraction",
        AllocatorConfig.tether_acceleration_fraction,
        "share of the reel start-up acceleration limit (5 m/s^2) used [-]",
        min_value=1e-3,
        max_value=1.0,
    ),
    ParameterSpec(
        "initial_radii_m",
        [float(v) for v in PAPER_INITIAL_RADII_M],
        "r_x, r_y, r_z the commands start from when no measured inertia came first [m]",
        min_value=0.0,
        max_value=100.0,
        length=3,
    ),
    ParameterSpec(
        "initialize_from_measured_inertia",
        True,
        "start from the radii of the first /splitter/inertia (projected) if it comes first",
    ),
    ParameterSpec(
        "answer_state_without_setpoints",
        True,
        "while no node publishes setpoints, answer each control tick of /splitter/inertia "
        "from the last good setpoint (lockstep keeps running)",
    ),
    ParameterSpec(
        "diagnostics_period_s",
        0.1,
        "diagnostics period in simulated time [s]",
        min_value=1e-3,
        max_value=100.0,
        live=True,
    ),
    ParameterSpec(
        "command_lead",
        False,
        "stamp commands ahead of their inputs by the latency measured, as points of a "
        "trajectory the simulator follows at their stamps (real time; lockstep needs "
        "each tick answered with its own stamp)",
    ),
    ParameterSpec(
        "command_lead_margin_s",
        0.002,
        "real time: commands are stamped ahead of their input by the largest latency "
        "measured plus this margin for their way to the simulator, in whole control "
        "periods (lockstep: latency 0, no lead) [s]",
        min_value=0.0,
        max_value=1.0,
        live=True,
    ),
    ParameterSpec(
        "command_lead_window_s",
        2.0,
        "the command lead plans for the largest input latency of this much simulated time [s]",
        min_value=0.0,
        max_value=100.0,
        live=True,
    ),
    ParameterSpec(
        "command_lead_max_s",
        0.5,
        "longest command lead: a larger latency is followed late, not planned for [s]",
        min_value=0.0,
        max_value=5.0,
        live=True,
    ),
)
# The live ones are read by the allocator on every tick (the speed and acceleration
# shares size its limiters when it is built: read-only).


class _Window:
    """What happened since the last diagnostics message."""

    def __init__(self) -> None:
        self.answered = 0
        self.fallback = 0
        self.saturated = 0
        self.rate_limited = 0
        self.rejected = 0
        self.max_saturation = 0.0
        self.min_margin = math.inf
        self.max_joint_speed = 0.0
        self.max_tether_speed = 0.0


class IkTetherAllocatorNode(Node):
    """Answers inertia setpoints with rate-limited, taut-tether joint commands."""

    def __init__(self, **kwargs) -> None:
        overrides = list(kwargs.pop("parameter_overrides", None) or [])
        if not any(p.name == "use_sim_time" for p in overrides):
            overrides.append(Parameter("use_sim_time", value=True))
        super().__init__(NODE_NAME, parameter_overrides=overrides, **kwargs)
        try:
            values = declare_parameters(self, PARAMETERS, on_live_change=self._apply_live)
            self.model = RobotModel()
            self.config = self._allocator_config(values)
            self._initial_radii = self._checked_radii(values["initial_radii_m"])
        except InvalidParameterError:
            self.destroy_node()
            raise
        self._period_ns = round(self.config.control_period_s * 1e9)
        self._lead = CommandLead(self._period_ns)
        self._lead_enabled = bool(values["command_lead"])
        self._apply_lead(values)
        self._latency = InputLatency()  # simulated clock at use - stamp, per input
        self._last_command_t: int | None = None  # stamp of the last command answering a tick
        # [kg m^2] inertia the commands plan at their stamps (the last second), to predict
        # the body rate at a command stamped ahead of its input
        self._planned_inertia: dict[int, np.ndarray] = {}
        self._diagnostics_ns = round(float(values["diagnostics_period_s"]) * 1e9)
        self._init_from_measured = bool(values["initialize_from_measured_inertia"])
        self._fallback_enabled = bool(values["answer_state_without_setpoints"])

        self.allocator: TetherLimbAllocator | None = None
        self.last_allocation: Allocation | None = None
        self._last_good_setpoint: np.ndarray | None = None
        self._w: np.ndarray | None = None
        self._imu_t_ns: int | None = None
        self._stamps = StampGate(MAX_STAMP_LEAD_NS)
        self.max_setpoint_kg_m2 = SETPOINT_LIMIT_FACTOR * float(
            np.max(reachable_inertia_bounds(self.model)[1])
        )
        self._pending_fallback_t: int | None = None
        self._last_answered_t: int | None = None
        self._last_diagnostics_t: int | None = None
        self._window = _Window()

        self._commands_pub = self.create_publisher(
            JointState, names.JOINT_COMMANDS, qos_for(names.JOINT_COMMANDS)
        )
        self._diagnostics_pub = self.create_publisher(
            DiagnosticArray, names.DIAGNOSTICS, qos_for(names.DIAGNOSTICS)
        )
        self.create_subscription(
            Vector3Stamped,
            names.INERTIA_SETPOINT,
            self._on_setpoint,
            qos_for(names.INERTIA_SETPOINT),
        )
        self.create_subscription(Imu, names.IMU, self._on_imu, qos_for(names.IMU))
        self.create_subscription(
            Vector3Stamped, names.INERTIA, self._on_inertia, qos_for(names.INERTIA)
        )
        self.get_logger().info(
            f"ik_tether_allocator ready: tick {self.config.control_period_s * 1e3:g} ms, "
            f"tension margin {self.config.tension_margin_n:g} N, joint speed "
            f"{self.model.joint_speed_max_rad_s * self.config.speed_fraction:.1f} rad/s, reel "
            f"{self.model.tether_speed_max_m_s * self.config.speed_fraction:.2f} m/s"
        )

    # --- parameters ------------------------------------------------------------------
    @staticmethod
    def _allocator_config(values: dict) -> AllocatorConfig:
        try:
            return AllocatorConfig(
                control_period_s=float(values["control_period_s"]),
                tension_margin_n=float(values["tension_margin_n"]),
                low_spin_tension_fraction=float(values["low_spin_tension_fraction"]),
                reference_velocity_window_s=float(values["reference_velocity_window_s"]),
                speed_fraction=float(values["speed_fraction"]),
                limb_acceleration_fraction=float(values["limb_acceleration_fraction"]),
                tether_acceleration_fraction=float(values["tether_acceleration_fraction"]),
            )
        except ValueError as exc:  # the config names its field, the same as the parameter
            field = next((k for k in values if f".{k} " in str(exc)), "allocator parameters")
            raise InvalidParameterError(f"parameter '{field}': {exc}") from exc

    def _apply_live(self, values: Mapping[str, ParameterValue]) -> None:
        """A live parameter change, applied from the next tick on."""
        config = self._allocator_config(dict(values))
        self.config = config
        if self.allocator is not None:
            self.allocator.config = config
        self._diagnostics_ns = round(float(values["diagnostics_period_s"]) * 1e9)
        self._apply_lead(values)

    def _apply_lead(self, values: Mapping[str, ParameterValue]) -> None:
        lead = self._lead
        lead.margin_ns = round(float(values["command_lead_margin_s"]) * 1e9)
        lead.window_ns = round(float(values["command_lead_window_s"]) * 1e9)
        lead.max_lead_ns = round(float(values["command_lead_max_s"]) * 1e9)

    def _checked_radii(self, radii: list[float]) -> np.ndarray:
        r = np.array(radii, dtype=float)
        lo, hi = self.model.radii_min_m, self.model.radii_max_m
        if np.any(r < lo) or np.any(r > hi):
            raise InvalidParameterError(
                f"parameter 'initial_radii_m' {r.tolist()} must lie within "
                f"{np.round(lo, 4).tolist()} .. {np.round(hi, 4).tolist()} m "
                "(tether length and knee range)"
            )
        return r

    def _ensure_allocator(self, radii: np.ndarray | None = None) -> TetherLimbAllocator:
        if self.allocator is None:
            start = self._initial_radii if radii is None else radii
            self.allocator = TetherLimbAllocator(self.model, self.config, start)
        return self.allocator

    # --- callbacks -----------------------------------------------------------------------
    def _clock_ns(self) -> int | None:
        """Simulated time of the node's clock [ns], None without a /clock reading yet."""
        clock = self.get_clock()
        if not getattr(clock, "ros_time_is_active", False):
            return None  # wall-clock time says nothing about simulated stamps
        now = clock.now().nanoseconds
        return now if now > 0 else None

    def _checked_stamp(self, topic: str, key: str, msg, answers_a_tick: bool = False) -> int | None:
        """The message's stamp [ns] if it may be used, else None (warned and counted).

        Rejected: negative or malformed, earlier than the last stamp of ``topic`` (or,
        ``answers_a_tick``, than the last tick answered), or more than
        ``MAX_STAMP_LEAD_NS`` ahead of the node's time.
        """
        try:
            t_ns = checked_stamp_from_msg(msg.header.stamp)
            self._stamps.check(topic, t_ns, self._clock_ns)
            last = self._last_answered_t
            if answers_a_tick and last is not None and t_ns < last:
                raise MessageValidationError(
                    f"header.stamp: {t_ns * 1e-9:.9f} s is earlier than the last tick "
                    f"answered {last * 1e-9:.9f} s"
                )
        except MessageValidationError as exc:
            self._window.rejected += 1
            warn_throttled(
                self, key, f"rejected {topic}: {exc}; dropped, the node keeps its last good data"
            )
            return None
        self._stamps.accept(topic, t_ns)
        return t_ns

    def _on_imu(self, msg: Imu) -> None:
        t_ns = self._checked_stamp(names.IMU, "imu", msg)
        if t_ns is None:
            return
        try:
            sample = imu_from_msg(msg)
            if msg.header.frame_id != names.BASE_FRAME:
                raise MessageValidationError(
                    f"header.frame_id: expected '{names.BASE_FRAME}', got {msg.header.frame_id!r}"
                )
            w = sample.angular_velocity_rad_s
            if np.any(np.abs(w) > MAX_BODY_RATE_RAD_S):
                raise MessageValidationError(
                    f"angular_velocity: {w.tolist()} rad/s beyond {MAX_BODY_RATE_RAD_S:g} rad/s"
                )
        except MessageValidationError as exc:
            self._window.rejected += 1
            warn_throttled(self, "imu", f"rejected /splitter/imu: {exc}; keeping the last good")
            return
        self._w = w
        self._imu_t_ns = t_ns
        if self._pending_fallback_t is not None and self._pending_fallback_t == t_ns:
            self._answer_fallback(t_ns)

    def _on_inertia(self, msg: Vector3Stamped) -> None:
        t_ns = self._checked_stamp(names.INERTIA, "inertia", msg)
        if t_ns is None:
            return
        try:
            sample = principal_inertia_from_msg(msg)
        except MessageValidationError as exc:
            self._window.rejected += 1
            warn_throttled(self, "inertia", f"rejected /splitter/inertia: {exc}")
            return
        if self.allocator is None and self._init_from_measured:
            self._ensure_allocator(project_inertia(self.model, sample.vector).radii_m)
        if not self._fallback_enabled or t_ns % self._period_ns != 0:
            return
        if self.count_publishers(names.INERTIA_SETPOINT) > 0:
            return
        if self.count_publishers(names.IMU) == 0 or self._imu_t_ns == t_ns:
            self._answer_fallback(t_ns)
        else:
            self._pending_fallback_t = t_ns  # answered when the IMU of this tick arrives

    def _checked_setpoint(self, msg: Vector3Stamped) -> np.ndarray:
        """The setpoint [kg m^2]: finite, each moment in (0, max_setpoint_kg_m2], frame base."""
        sample = vector3_from_msg(msg)
        if sample.frame_id != names.BASE_FRAME:
            raise MessageValidationError(
                f"header.frame_id: expected '{names.BASE_FRAME}', got {sample.frame_id!r}"
            )
        setpoint = sample.vector
        if np.any(setpoint <= 0.0) or np.any(setpoint > self.max_setpoint_kg_m2):
            raise MessageValidationError(
                f"vector: moments must be in (0, {self.max_setpoint_kg_m2:.4g}] kg m^2, "
                f"got {setpoint.tolist()}"
            )
        return setpoint

    def _on_setpoint(self, msg: Vector3Stamped) -> None:
        t_ns = self._checked_stamp(
            names.INERTIA_SETPOINT, "setpoint_stamp", msg, answers_a_tick=True
        )
        if t_ns is None:
            return
        try:
            setpoint = self._checked_setpoint(msg)
        except MessageValidationError as exc:
            self._window.rejected += 1
            warn_throttled(
                self,
                "setpoint",
                f"rejected /splitter/inertia_setpoint at t = {t_ns * 1e-9:.3f} s: {exc}; "
                "answering from the last good setpoint",
            )
            self._answer(t_ns, self._hold_setpoint())
            return
        self._last_good_setpoint = setpoint
        self._answer(t_ns, setpoint)

    # --- answering -----------------------------------------------------------------------
    def _hold_setpoint(self) -> np.ndarray:
        """The last good setpoint, or the inertia of the radii commanded now."""
        if self._last_good_setpoint is not None:
            return self._last_good_setpoint
        radii = self._ensure_allocator().radii_m
        return principal_inertia(self.model, radii if radii is not None else self._initial_radii)

    def _answer_fallback(self, t_ns: int) -> None:
        self._pending_fallback_t = None
        if self._last_answered_t is not None and self._last_answered_t >= t_ns:
            return  # that tick is answered (or past): a late state changes nothing
        self._window.fallback += 1
        self._answer(t_ns, self._hold_setpoint())

    def _answer(self, t_ns: int, setpoint: np.ndarray) -> None:
        """Answer the input tick ``t_ns``: one command per control period it covers.

        The commands are stamped ahead of the input by the latency measured
        (:class:`~splitter_ik.core.command_lead.CommandLead`; lockstep: none).
        """
        now = self._clock_ns()
        self._latency.record("inertia_setpoint", t_ns, now)
        if self._lead_enabled:
            self._lead.record(t_ns, now)
            stamps = self._lead.output_stamps(t_ns, self._last_command_t)
        else:
            stamps = [t_ns]
        for stamp in stamps:
            if not self._command(stamp, setpoint, t_ns):
                return
        self._last_answered_t = t_ns
        self._maybe_publish_diagnostics(t_ns)

    def _rate_at(self, t_ns: int, input_t_ns: int) -> np.ndarray | None:
        """The last body rate measured, predicted for a command stamped ``t_ns``.

        Lockstep (a command stamped with its input) and before any lead: as measured.
        """
        w, allocator = self._w, self.allocator
        if w is None or t_ns == input_t_ns or allocator is None or allocator.radii_m is None:
            return w
        measured_t = self._imu_t_ns or 0
        then = self._planned_inertia.get(measured_t - measured_t % self._period_ns)
        if then is None:
            return w
        return angular_velocity_after_morphing(
            w, then, principal_inertia(self.model, allocator.radii_m)
        )

    def _command(self, t_ns: int, setpoint: np.ndarray, setpoint_t_ns: int) -> bool:
        """Allocate and publish the command stamped ``t_ns``; False when refused."""
        allocator = self._ensure_allocator()
        try:
            # stamps were checked (never before the last tick) and the setpoint validated
            allocation = allocator.allocate(
                t_ns, setpoint, self._rate_at(t_ns, setpoint_t_ns), setpoint_t_ns
            )
            command = joint_state_to_msg(t_ns, allocation.joint_position, allocation.joint_velocity)
        except ValueError as exc:  # MessageValidationError too: nothing sent, state kept
            self.get_logger().error(
                f"t = {t_ns * 1e-9:.3f} s: tick not answered, the allocator refused it: {exc}",
                throttle_duration_sec=2.0,
            )
            return False
        if allocation.saturated:
            warn_throttled(
                self,
                "projected",
                f"setpoint {np.round(allocation.requested_inertia_kg_m2, 4).tolist()} kg m^2 at "
                f"t = {t_ns * 1e-9:.3f} s is unreachable: projected onto the reachable set",
            )
        self._commands_pub.publish(command)
        self.last_allocation = allocation
        self._last_command_t = t_ns
        if self._lead.lead_ns > 0:
            planned = self._planned_inertia
            planned[t_ns] = allocation.achieved_inertia_kg_m2
            for old in [t for t in planned if t < t_ns - LEAD_HISTORY_NS]:
                del planned[old]
        self._account(allocation)
        return True

    def _account(self, a: Allocation) -> None:
        w = self._window
        w.answered += 1
        w.saturated += int(a.saturated)
        w.rate_limited += int(a.rate_limited)
        if a.saturated:  # distance from the request to the reachable set
            projected = project_inertia(self.model, a.requested_inertia_kg_m2)
            saturation = float(np.linalg.norm(projected.saturation_kg_m2))
            w.max_saturation = max(w.max_saturation, saturation)
        if math.isfinite(a.tension_margin_n):
            w.min_margin = min(w.min_margin, a.tension_margin_n)
        w.max_joint_speed = max(
            w.max_joint_speed, float(np.max(np.abs(a.joint_velocity[:TETHER_INDEX])))
        )
        w.max_tether_speed = max(w.max_tether_speed, abs(float(a.joint_velocity[TETHER_INDEX])))

    def _maybe_publish_diagnostics(self, t_ns: int) -> None:
        last = self._last_diagnostics_t
        if last is not None and t_ns // self._diagnostics_ns == last // self._diagnostics_ns:
            return
        self._last_diagnostics_t = t_ns
        try:
            msg = diagnostics_to_msg(t_ns, [self.diagnostics_status()])
        except MessageValidationError as exc:
            self.get_logger().error(f"diagnostics not published: {exc}", throttle_duration_sec=2.0)
        else:
            self._diagnostics_pub.publish(msg)
        self._window = _Window()

    def diagnostics_status(self) -> DiagnosticStatusSample:
        """The status of the current window (also what the next /diagnostics carries)."""
        w, a = self._window, self.last_allocation
        values: dict[str, float | int | str | bool] = {
            "ticks_answered": w.answered,
            "ticks_answered_without_setpoint": w.fallback,
            "setpoints_rejected": w.rejected,
            "setpoints_projected": w.saturated,
            "ticks_rate_limited": w.rate_limited,
            "max_saturation_kg_m2": w.max_saturation,
            "max_limb_joint_speed_rad_s": w.max_joint_speed,
            "max_tether_speed_m_s": w.max_tether_speed,
            "tension_margin_setting_n": self.config.tension_margin_n,
            "command_lead_ms": self._lead.lead_ns * 1e-6,
            **self._latency.values(),
        }
        for key, count in sorted(rejection_counts(self).items()):
            values[f"total_warnings_{key}"] = count
        values.update(parameter_diagnostics(self))
        problems = []
        if a is not None:
            values.update(
                {
                    "saturated": a.saturated,
                    "rate_limited": a.rate_limited,
                    "r_x_m": float(a.radii_m[0]),
                    "r_y_m": float(a.radii_m[1]),
                    "r_z_m": float(a.radii_m[2]),
                    "tether_length_m": float(a.joint_position[TETHER_INDEX]),
                }
            )
            if math.isfinite(a.tension_n):
                values["tension_n"] = a.tension_n
                values["required_tension_n"] = a.required_tension_n
                values["tension_margin_n"] = a.tension_margin_n
        if math.isfinite(w.min_margin):
            values["min_tension_margin_n"] = w.min_margin
            if w.min_margin < 0.0:
                problems.append("tension below the required margin")
        elif self._w is None:
            problems.append("no angular velocity yet: tension not checked")
        if w.rejected:
            problems.append(f"{w.rejected} input(s) rejected")
        if w.saturated:
            problems.append(f"{w.saturated} setpoint(s) projected onto the reachable set")
        level = 1 if problems else 0
        message = "; ".join(problems) if problems else "tracking"
        if w.rate_limited and not problems:
            message = "tracking, rate limited"
        return DiagnosticStatusSample(name=STATUS_NAME, level=level, message=message, values=values)


def main(args: list[str] | None = None) -> int:
    """Spin until Ctrl-C or shutdown; an invalid parameter exits with 1 naming it."""
    return run_node(lambda stop: IkTetherAllocatorNode(), NODE_NAME, args)


if __name__ == "__main__":
    raise SystemExit(main())
