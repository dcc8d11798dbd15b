"""``gait_phase_manager``: sequences Launch, In-Flight, Jump, Landing and Landed.

A thin ROS layer over :class:`splitter_mpc.core.gait.GaitPhaseMachine`.

Lockstep (docs/ARCHITECTURE.md, item 5): the node answers control tick ``t``
(``t`` on the ``control_period_s`` grid) once it holds ``/splitter/odom``, both
contact wrenches and ``/splitter/joint_states`` stamped ``t`` (and
``/splitter/inertia`` with ``attitude_reference: momentum_aligned``, the one mode
that needs it); it publishes ``/splitter/jump_command`` stamped ``t`` (a zero
wrench when not thrusting) on every tick it answers. Waiting for all inputs of
the same tick makes the answer independent of the order in which DDS delivers
them, so runs repeat.

Bad input never raises out of a callback and never resets the phase machine;
every rejection is a throttled warning, counted and reported on ``/diagnostics``:

* a message whose stamp is negative, earlier than the last one of its topic (a
  stamp of 0 once time has advanced) or more than ``MAX_STAMP_LEAD_NS`` ahead of
  the node's time (its simulated clock, or the newest stamp it accepted) is
  dropped: it is filed under no tick and does not replace the last good message;
* a well-stamped message that fails validation (NaN, non-unit quaternion, wrong
  frame, unknown / missing joint names, a magnitude beyond the plausibility
  limits ``MAX_POSITION_M``, ``MAX_SPEED_M_S``, ``MAX_BODY_RATE_RAD_S``,
  ``MAX_CONTACT_FORCE_N``, ``MAX_TETHER_LENGTH_M``, inertia outside (0, 1e4] kg
  m^2) still answers its tick, from the last good message of that topic, so
  lockstep never stalls on bad data.

Subscribes: ``/splitter/odom``, ``/splitter/hemi_{a,b}/contact_wrench`` (stance:
world-z force above ``stance_force_threshold_n``), ``/splitter/joint_states``
(``r_x`` = tether joint / 2), ``/splitter/inertia`` in mode ``momentum_aligned``
only (the measured principal moments: with the odom's body rate, the angular
momentum that mode aligns the reference with; the very numbers the MPC and the
recorded run see).
Publishes: ``/splitter/jump_command`` (every tick), ``/splitter/gait_phase``,
``/splitter/attitude_reference`` and ``/splitter/attitude_reference_pose``
(latched, on change), ``/diagnostics`` (every ``diagnostics_period_s`` of
simulated time).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, TwistStamped, Vector3Stamped, WrenchStamped
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from splitter_mpc.core.gait import (
    ATTITUDE_REFERENCE_MODES,
    NS_PER_S,
    GaitConfig,
    GaitOutput,
    GaitPhaseMachine,
    gait_config_from_parameters,
    seconds_to_ns,
)
from splitter_mpc.core.tick_inputs import TickAssembler
from splitter_msgs_py import names
from splitter_msgs_py.conversions import (
    DiagnosticStatusSample,
    MessageValidationError,
    checked_stamp_from_msg,
    diagnostics_to_msg,
    joint_state_from_msg,
    odom_from_msg,
    pose_to_msg,
    principal_inertia_from_msg,
    twist_to_msg,
    wrench_from_msg,
    wrench_to_msg,
)
from splitter_msgs_py.core.latency import InputLatency
from splitter_msgs_py.core.stamps import MAX_STAMP_LEAD_NS, StampGate
from splitter_msgs_py.node_pattern import run_node
from splitter_msgs_py.parameters import (
    READ_ONLY_NOTE,
    InvalidParameterError,
    ParameterSpec,
    ParameterValue,
    declare_parameters,
    parameter_diagnostics,
    rejection_counts,
    warn_throttled,
)
from splitter_msgs_py.qos import LATCHED_QOS, qos_for

NODE_NAME = "gait_phase_manager"
DEFAULTS = GaitConfig()
TETHER_INDEX = names.JOINT_INDEX[names.TETHER_JOINT]
TICK_INPUTS = (names.ODOM, names.CONTACT_WRENCH_A, names.CONTACT_WRENCH_B, names.JOINT_STATES)
# and /splitter/inertia when the attitude reference needs it (GaitConfig.needs_principal_inertia)
# Plausibility limits of the measured state: beyond them a message is corrupt (or the
# simulation diverged) and is rejected, so the phase machine only sees sane numbers.
MAX_POSITION_M = 1.0e6  # [m] per odom position component (runs stay within ~100 m)
MAX_SPEED_M_S = 1.0e3  # [m/s] per odom velocity component (a jump is a few m/s)
MAX_BODY_RATE_RAD_S = 1.0e3  # [rad/s] per odom body-rate component (spin ~1 rad/s)
MAX_CONTACT_FORCE_N = 1.0e7  # [N] per contact force component (weight ~ 30 N on the moon)
MAX_TETHER_LENGTH_M = 100.0  # [m] tether joint position (the reel holds 6 m)

# The jump plan: float arrays that a params file may give as [] (read as "not set").
PLAN_PARAMETERS = (
    ParameterSpec("jump_times_s", [], "planned jump times: earliest thrust start [s]"),
    ParameterSpec(
        "jump_forces_n", [], "planned thrust forces, world frame, 3 values per jump (x, y, z) [N]"
    ),
    ParameterSpec("jump_durations_s", [], "planned thrust durations, one per jump [s]"),
)
PARAMETERS = (
    ParameterSpec(
        "stance_force_threshold_n",
        DEFAULTS.stance_force_threshold_n,
        "contact normal force above which a hemi is in stance [N]",
        min_value=1e-3,
        max_value=1e4,
        live=True,
    ),
    ParameterSpec(
        "touchdown_debounce_s",
        DEFAULTS.touchdown_debounce_ns / NS_PER_S,
        "stance without a break for at least this long means touchdown [s]",
        min_value=0.0,
        max_value=1.0,
        live=True,
    ),
    ParameterSpec(
        "liftoff_debounce_s",
        DEFAULTS.liftoff_debounce_ns / NS_PER_S,
        "no stance for longer than this means lift-off [s]",
        min_value=0.0,
        max_value=1.0,
        live=True,
    ),
    ParameterSpec(
        "landed_speed_m_s",
        DEFAULTS.landed_speed_m_s,
        "centre-of-mass speed below which the robot is at rest [m/s]",
        min_value=1e-4,
        max_value=10.0,
        live=True,
    ),
    ParameterSpec(
        "landed_angular_speed_rad_s",
        DEFAULTS.landed_angular_speed_rad_s,
        "angular speed below which the robot is at rest [rad/s]",
        min_value=1e-4,
        max_value=10.0,
        live=True,
    ),
    ParameterSpec(
        "landed_dwell_s",
        DEFAULTS.landed_dwell_ns / NS_PER_S,
        "time at rest in stance before LANDED [s]",
        min_value=0.0,
        max_value=60.0,
        live=True,
    ),
    ParameterSpec(
        "w_ref_rad_s",
        list(DEFAULTS.w_ref_rad_s),
        "flight angular velocity reference, base frame [rad/s]",
        length=3,
    ),
    ParameterSpec(
        "landing_w_ref_rad_s",
        list(DEFAULTS.landing_w_ref_rad_s),
        "angular velocity reference during landing, base frame [rad/s]",
        length=3,
    ),
    ParameterSpec(
        "attitude_reference",
        DEFAULTS.attitude_reference,
        "attitude reference: hold the first measured attitude (initial), propagate it with "
        "w_ref (integrate_w_ref), or propagate it with w_ref after turning the body axis of "
        "w_ref onto the measured angular momentum (momentum_aligned)",
        choices=ATTITUDE_REFERENCE_MODES,
    ),
    ParameterSpec(
        "control_period_s",
        0.01,
        "control tick period: ticks answered are the multiples of it [s]",
        min_value=0.001,
        max_value=1.0,
    ),
    ParameterSpec(
        "diagnostics_period_s",
        0.1,
        "diagnostics period in simulated time, a multiple of control_period_s [s]",
        min_value=0.001,
        max_value=10.0,
    ),
)


def declare_plan_arrays(node: Node) -> dict[str, list[float]]:
    """Declare and validate the plan's float arrays, an empty or absent one meaning no jump.

    ``declare_parameters`` reads a ``[]`` given in a params file as an unset
    value and rejects it; here it is the empty plan. Same descriptors, same checks.
    """
    values: dict[str, list[float]] = {}
    for spec in PLAN_PARAMETERS:
        descriptor = spec.descriptor()
        descriptor.dynamic_typing = True  # a YAML list of integers is accepted
        try:
            node.declare_parameter(spec.name, spec.default, descriptor)
        except ParameterException as exc:
            raise InvalidParameterError(f"parameter '{spec.name}': {exc}") from exc
        raw = node.get_parameter(spec.name).value
        values[spec.name] = spec.validate([] if raw is None else list(raw))
    return values


def declare_string_array(node: Node, name: str, description: str) -> list[str]:
    """Declare a string-array parameter (empty when not given) and read it.

    ``ParameterSpec`` covers numbers and strings; a string array is declared here
    with the same error contract (``InvalidParameterError`` naming it). Typing is
    dynamic because an empty list arrives untyped (a params file's ``[]`` is
    unset, an override's ``[]`` is a byte array): any empty value means none.
    """
    descriptor = ParameterDescriptor(
        name=name,
        description=description + READ_ONLY_NOTE,
        dynamic_typing=True,
        read_only=True,
    )
    try:
        node.declare_parameter(name, [], descriptor)
    except ParameterException as exc:
        raise InvalidParameterError(f"parameter '{name}': {exc}") from exc
    value = node.get_parameter(name).value
    if value is None or (isinstance(value, list | tuple | bytes) and len(value) == 0):
        return []
    if not isinstance(value, list | tuple) or not all(isinstance(v, str) for v in value):
        raise InvalidParameterError(f"parameter '{name}' must be a list of strings, got {value!r}")
    return list(value)


def _named_parameter_error(exc: ValueError) -> InvalidParameterError:
    """``InvalidParameterError`` from a core ``ValueError`` whose text starts with the name."""
    name, _, reason = str(exc).partition(": ")
    return InvalidParameterError(f"parameter '{name}': {reason}")


class GaitPhaseManagerNode(Node):
    """Answers every control tick with a jump command; publishes phase and references."""

    def __init__(self, **kwargs) -> None:
        super().__init__(NODE_NAME, **kwargs)
        try:
            config, periods = self._read_parameters()
        except InvalidParameterError:
            self.destroy_node()
            raise
        self._control_period_ns, self._diagnostics_period_ns = periods
        self._machine = GaitPhaseMachine(config)
        self.ticks = TickAssembler(
            self._control_period_ns,
            TICK_INPUTS + ((names.INERTIA,) if config.needs_principal_inertia else ()),
        )
        self._ticks_answered = 0
        self._latency = InputLatency()  # a tick's state: simulated clock when used - stamp
        self._stale_ticks = 0
        self._last_output: GaitOutput | None = None
        self._last_change: tuple[int, str] = (0, "")  # (stamp [ns], reason) of the last change
        self._stamps = StampGate(MAX_STAMP_LEAD_NS)

        self._jump_pub = self.create_publisher(
            WrenchStamped, names.JUMP_COMMAND, qos_for(names.JUMP_COMMAND)
        )
        self._phase_pub = self.create_publisher(String, names.GAIT_PHASE, LATCHED_QOS)
        self._w_ref_pub = self.create_publisher(TwistStamped, names.ATTITUDE_REFERENCE, LATCHED_QOS)
        self._q_ref_pub = self.create_publisher(
            PoseStamped, names.ATTITUDE_REFERENCE_POSE, LATCHED_QOS
        )
        self._diagnostics_pub = self.create_publisher(
            DiagnosticArray, names.DIAGNOSTICS, qos_for(names.DIAGNOSTICS)
        )
        self.create_subscription(Odometry, names.ODOM, self._on_odom, qos_for(names.ODOM))
        for topic in names.CONTACT_WRENCHES:
            self.create_subscription(
                WrenchStamped,
                topic,
                lambda msg, topic=topic: self._on_contact(topic, msg),
                qos_for(topic),
            )
        self.create_subscription(
            JointState, names.JOINT_STATES, self._on_joint_states, qos_for(names.JOINT_STATES)
        )
        if config.needs_principal_inertia:
            self.create_subscription(
                Vector3Stamped, names.INERTIA, self._on_inertia, qos_for(names.INERTIA)
            )
        self.get_logger().info(
            f"{len(config.jumps)} jump(s) planned at "
            f"{[j.time_ns / 1e9 for j in config.jumps]} s; attitude reference "
            f"'{config.attitude_reference}', w_ref {list(config.w_ref_rad_s)} rad/s"
        )

    @property
    def config(self) -> GaitConfig:
        """The validated configuration of the gait phase machine."""
        return self._machine.config

    # -- parameters ----------------------------------------------------------------------
    def _read_parameters(self) -> tuple[GaitConfig, tuple[int, int]]:
        values = declare_parameters(self, PARAMETERS, on_live_change=self._apply_live)
        self._plan = declare_plan_arrays(self)
        self._plan["jump_hemis"] = declare_string_array(
            self, "jump_hemis", "pushing hemi per planned jump: 'a', 'b' or 'auto'"
        )
        values.update(self._plan)
        control_ns = seconds_to_ns(values["control_period_s"])
        diagnostics_ns = seconds_to_ns(values["diagnostics_period_s"])
        if diagnostics_ns % control_ns != 0:
            raise InvalidParameterError(
                f"parameter 'diagnostics_period_s' ({values['diagnostics_period_s']} s) must be "
                f"a multiple of control_period_s ({values['control_period_s']} s)"
            )
        try:
            config = gait_config_from_parameters(values)
        except ValueError as exc:
            raise _named_parameter_error(exc) from exc
        return config, (control_ns, diagnostics_ns)

    def _apply_live(self, values: Mapping[str, ParameterValue]) -> None:
        """A live change of the contact and landing thresholds, from the next tick on."""
        try:
            config = gait_config_from_parameters({**values, **self._plan})
        except ValueError as exc:
            raise _named_parameter_error(exc) from exc
        self._machine.config = config

    # -- inputs --------------------------------------------------------------------------
    def _clock_ns(self) -> int | None:
        """Simulated time of the node's clock [ns], None without sim time or a /clock yet."""
        clock = self.get_clock()
        if not getattr(clock, "ros_time_is_active", False):
            return None  # wall-clock time says nothing about simulated stamps
        now = clock.now().nanoseconds
        return now if now > 0 else None

    def _checked_stamp(self, topic: str, msg) -> int | None:
        """The message's stamp [ns] if it may be used, else None (warned and counted)."""
        try:
            t_ns = checked_stamp_from_msg(msg.header.stamp)
            self._stamps.check(topic, t_ns, self._clock_ns)
        except MessageValidationError as exc:
            warn_throttled(
                self, topic, f"rejected {topic}: {exc}; dropped, keeping the last good message"
            )
            return None
        self._stamps.accept(topic, t_ns)
        return t_ns

    @staticmethod
    def _check_bound(field_name: str, values, limit: float, unit: str) -> None:
        if max(abs(v) for v in np.asarray(values, dtype=float).reshape(-1).tolist()) > limit:
            raise MessageValidationError(
                f"{field_name}: {np.asarray(values).tolist()} beyond +-{limit:g} {unit}"
            )

    def _on_odom(self, msg: Odometry) -> None:
        t_ns = self._checked_stamp(names.ODOM, msg)
        if t_ns is None:
            return
        try:
            if msg.header.frame_id != names.WORLD_FRAME:
                raise MessageValidationError(
                    f"header.frame_id: expected '{names.WORLD_FRAME}', got {msg.header.frame_id!r}"
                )
            if msg.child_frame_id != names.BASE_FRAME:  # the frame of the twist
                raise MessageValidationError(
                    f"child_frame_id: expected '{names.BASE_FRAME}', got {msg.child_frame_id!r}"
                )
            sample = odom_from_msg(msg)
            self._check_bound("pose.position", sample.position_m, MAX_POSITION_M, "m")
            self._check_bound("twist.linear", sample.velocity_world_m_s, MAX_SPEED_M_S, "m/s")
            self._check_bound(
                "twist.angular", sample.angular_velocity_rad_s, MAX_BODY_RATE_RAD_S, "rad/s"
            )
        except MessageValidationError as exc:
            self._reject(names.ODOM, t_ns, exc)
            return
        self._accept(names.ODOM, t_ns, sample)

    def _on_contact(self, topic: str, msg: WrenchStamped) -> None:
        t_ns = self._checked_stamp(topic, msg)
        if t_ns is None:
            return
        try:
            sample = wrench_from_msg(msg)
            if sample.frame_id != names.WORLD_FRAME:
                raise MessageValidationError(
                    f"header.frame_id: expected '{names.WORLD_FRAME}', got {sample.frame_id!r}"
                )
            self._check_bound("wrench.force", sample.force_n, MAX_CONTACT_FORCE_N, "N")
        except MessageValidationError as exc:
            self._reject(topic, t_ns, exc)
            return
        self._accept(topic, t_ns, sample)

    def _on_joint_states(self, msg: JointState) -> None:
        t_ns = self._checked_stamp(names.JOINT_STATES, msg)
        if t_ns is None:
            return
        try:
            sample = joint_state_from_msg(msg)
            tether = float(sample.position[TETHER_INDEX])
            if not 0.0 < tether <= MAX_TETHER_LENGTH_M:
                raise MessageValidationError(
                    f"position: tether length {tether} m is not in (0, {MAX_TETHER_LENGTH_M:g}] m"
                )
        except MessageValidationError as exc:
            self._reject(names.JOINT_STATES, t_ns, exc)
            return
        self._accept(names.JOINT_STATES, t_ns, sample)

    def _on_inertia(self, msg: Vector3Stamped) -> None:
        t_ns = self._checked_stamp(names.INERTIA, msg)
        if t_ns is None:
            return
        try:
            sample = principal_inertia_from_msg(msg)
        except MessageValidationError as exc:
            self._reject(names.INERTIA, t_ns, exc)
            return
        self._accept(names.INERTIA, t_ns, sample)

    def _accept(self, topic: str, t_ns: int, sample: object) -> None:
        self._collect(topic, t_ns, sample)

    def _reject(self, topic: str, t_ns: int, exc: MessageValidationError) -> None:
        warn_throttled(
            self, topic, f"rejected {topic} stamped {t_ns * 1e-9:.3f} s: {exc}; using last good"
        )
        self._collect(topic, t_ns, None)

    def _collect(self, topic: str, t_ns: int, sample: object | None) -> None:
        """File an input under its tick; answer the tick once all its inputs are in."""
        events = self.ticks.add(topic, t_ns, sample)
        for tick, had in events.dropped:
            self.get_logger().warning(
                f"tick {tick * 1e-9:.3f} s dropped: inputs never completed (had {list(had)})"
            )
        if events.completed is None:
            return
        t_done, inputs = events.completed
        for tick, had in events.skipped:
            self.get_logger().warning(
                f"tick {tick * 1e-9:.3f} s skipped: tick {t_done * 1e-9:.3f} s completed "
                f"first (had {list(had)})"
            )
        self._answer_tick(t_done, inputs)

    # -- the tick ------------------------------------------------------------------------
    def _answer_tick(self, t_ns: int, inputs: dict[str, object | None]) -> None:
        self._ticks_answered += 1
        self._latency.record("state", t_ns, self._clock_ns())
        if any(sample is None for sample in inputs.values()):
            self._stale_ticks += 1
        samples = self.ticks.samples(inputs)  # a rejected input: its topic's last good one
        odom, contact_a, contact_b, joints = (samples[topic] for topic in TICK_INPUTS)
        inertia = samples.get(names.INERTIA)
        output = None
        if any(sample is None for sample in samples.values()):
            warn_throttled(
                self, "no_good_input", f"tick {t_ns * 1e-9:.3f} s: no good input yet; zero thrust"
            )
        else:
            try:
                output = self._machine.update(
                    t_ns,
                    odom.position_m,
                    odom.velocity_world_m_s,
                    odom.orientation_wxyz,
                    odom.angular_velocity_rad_s,
                    0.5 * float(joints.position[TETHER_INDEX]),
                    (float(contact_a.force_n[2]), float(contact_b.force_n[2])),
                    None if inertia is None else inertia.vector,
                )
            except ValueError as exc:  # inputs are validated: a bug, reported, zero thrust
                self.get_logger().error(
                    f"tick {t_ns * 1e-9:.3f} s: gait update failed: {exc}",
                    throttle_duration_sec=2.0,
                )
        self._publish(t_ns, output)

    def _publish(self, t_ns: int, output: GaitOutput | None) -> None:
        try:
            if output is None:
                jump = wrench_to_msg(t_ns, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), names.WORLD_FRAME)
            else:
                jump = wrench_to_msg(
                    t_ns, output.jump_force_n, output.jump_torque_nm, names.WORLD_FRAME
                )
        except MessageValidationError as exc:
            self.get_logger().error(f"tick {t_ns * 1e-9:.3f} s: jump command refused ({exc}); zero")
            jump = wrench_to_msg(t_ns, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), names.WORLD_FRAME)
        if output is not None:  # the tick's phase and reference go out before its answer
            self._last_output = output
            if output.phase_changed:
                self.get_logger().info(
                    f"gait phase {output.phase.value} at t = {t_ns * 1e-9:.3f} s: {output.reason}"
                )
                self._last_change = (t_ns, output.reason)
                self._phase_pub.publish(String(data=output.phase.value))
            if output.reference is not None:
                self._publish_reference(output)
        self._jump_pub.publish(jump)
        if t_ns % self._diagnostics_period_ns == 0:
            self._publish_diagnostics(t_ns)

    def _publish_reference(self, output: GaitOutput) -> None:
        reference = output.reference
        try:
            twist = twist_to_msg(reference.stamp_ns, reference.w_ref_rad_s, names.BASE_FRAME)
            pose = pose_to_msg(reference.stamp_ns, reference.q_ref_wxyz, frame_id=names.WORLD_FRAME)
        except MessageValidationError as exc:
            self.get_logger().error(f"attitude reference not published: {exc}")
            return
        self._w_ref_pub.publish(twist)
        self._q_ref_pub.publish(pose)

    def _publish_diagnostics(self, t_ns: int) -> None:
        output = self._last_output
        rejected = sum(rejection_counts(self).values())
        values: dict[str, float | int | str | bool] = {
            "ticks_answered": self._ticks_answered,
            "ticks_with_rejected_input": self._stale_ticks,
            "rejected_messages": rejected,
            **self._latency.values(),
            **parameter_diagnostics(self),
        }
        if output is None:
            level, message = 1, "no good input yet"
        else:
            values.update(
                {
                    "phase": output.phase.value,
                    "time_in_phase_s": output.time_in_phase_ns * 1e-9,
                    "jumps_done": output.jumps_done,
                    "jumps_planned": output.jumps_planned,
                    "stance_a": output.stance[0],
                    "stance_b": output.stance[1],
                    "thrusting": output.thrusting,
                    "pushing_hemi": output.pushing_hemi or "",
                    "jump_waiting_for_stance": output.jump_waiting,
                    "on_ground": output.on_ground,
                    "last_change_s": self._last_change[0] * 1e-9,
                    "last_change_reason": self._last_change[1],
                    "hemi_a_height_m": output.hemi_height_m[0],
                    "hemi_b_height_m": output.hemi_height_m[1],
                    "jump_force_z_n": float(output.jump_force_n[2]),
                }
            )
            level = 1 if output.jump_waiting else 0
            message = output.phase.value
            if output.jump_waiting:
                message += " (jump due, waiting for its hemi to be in stance)"
        status = DiagnosticStatusSample(f"{NODE_NAME}: gait phase", level, message, values)
        try:
            self._diagnostics_pub.publish(diagnostics_to_msg(t_ns, [status]))
        except MessageValidationError as exc:
            self.get_logger().error(f"diagnostics not published: {exc}")


def main(args: list[str] | None = None) -> int:
    """Run the node until Ctrl-C or shutdown; an invalid parameter stops it with exit code 1."""
    return run_node(lambda stop: GaitPhaseManagerNode(), NODE_NAME, args)


if __name__ == "__main__":
    raise SystemExit(main())
