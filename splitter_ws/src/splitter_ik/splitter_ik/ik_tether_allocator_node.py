"""``ik_tether_allocator``: principal-inertia setpoints to joint commands, as a ROS 2 node.

A thin layer over :class:`splitter_ik.core.allocator_tick.AllocatorTick` (the tick's
rules, also driven by the library closed loop): messages in, its outputs published.

* ``/splitter/inertia_setpoint`` (Vector3Stamped, Ixx Iyy Izz [kg m^2]) stamped ``t``
  is answered with ``/splitter/joint_commands`` (JointState, 25 positions and
  velocities) stamped ``t`` (docs/ARCHITECTURE.md, lockstep protocol item 4): a point
  of a piecewise-linear reference, the position planned at ``t`` and the velocity
  held until the next tick (:class:`~splitter_ik.core.allocator.Allocation`).
* ``/splitter/imu`` gives the body angular velocity for the taut-tether limit, and
  its specific force whether the robot is in free fall (the limit applies) or held
  by its feet.
* ``/splitter/inertia`` (the measured state): the first one sets the starting radii
  (``initialize_from_measured_inertia``); and while nothing publishes setpoints, each
  control tick of it is answered from the last good setpoint, so that a lockstep
  simulator keeps running without the MPC (with the IMU of the same tick when an
  IMU publisher exists).
* ``/splitter/joint_states`` against the commands it sent: faulty joints
  (:mod:`splitter_ik.core.joint_health`; parameter ``fault_handling``, thresholds
  ``stuck_window_s``, ``envelope_margin_rad``, ... set at start-up). Once one is
  found the allocator re-plans without it (``splitter_model.redundancy``) and
  publishes ``/splitter/joint_health`` every tick: the faulty joints, their symptoms
  and the radius bounds that remain (the MPC plans within them).
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
  the last good setpoint (while the MPC is the topic's one publisher; with a
  stranger on it, the tick waits for a good setpoint);
* an IMU with a bad quaternion, non-finite values, a body rate above
  ``MAX_BODY_RATE_RAD_S`` or a frame other than ``base``; a measured inertia that is
  not ``base``-framed moments in ``(0, 1e4]`` kg m^2: the last good one is kept.

A reachable-set miss is not an error: the setpoint is projected onto the reachable
set (throttled warning). Invalid parameters stop the node at start-up with a
message naming the parameter. Runs on simulated time unless ``use_sim_time`` is
overridden.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
from rclpy.node import Node
from sensor_msgs.msg import Imu, JointState

from splitter_ik.core.allocator import AllocatorConfig
from splitter_ik.core.allocator_tick import (
    AllocatorStatus,
    AllocatorTick,
    AllocatorTickSettings,
    TickOutput,
)
from splitter_ik.core.command_lead import CommandLeadConfig
from splitter_ik.core.joint_health import JointHealthConfig
from splitter_model.model import RobotModel
from splitter_msgs_py import names
from splitter_msgs_py.conversions import (
    DiagnosticStatusSample,
    diagnostics_to_msg,
    imu_from_msg,
    joint_health_status,
    joint_state_from_msg,
    joint_state_to_msg,
    principal_inertia_from_msg,
    vector3_from_msg,
)
from splitter_msgs_py.core.stamps import MessageValidationError
from splitter_msgs_py.node_pattern import admitted_stamp, default_sim_time, run_node, sim_clock_ns
from splitter_msgs_py.parameters import (
    InvalidParameterError,
    ParameterValue,
    config_from_values,
    declare_parameters,
    parameter_diagnostics,
    rejection_counts,
    specs_from_config,
    warn_throttled,
)
from splitter_msgs_py.qos import qos_for

NODE_NAME = "ik_tether_allocator"
STATUS_NAME = f"{NODE_NAME}: allocation"
CONFIGS = (AllocatorConfig, AllocatorTickSettings, CommandLeadConfig)  # the core's settings
# the fault detector's thresholds: set at start-up (a detector re-tuned mid-flight would
# judge old commands by new rules)
HEALTH_CONFIG = JointHealthConfig
PARAMETERS = tuple(
    spec for config in (*CONFIGS, HEALTH_CONFIG) for spec in specs_from_config(config)
)
# topic: (warning key of a bad stamp, of bad content; what a bad content leads to)
INPUTS = {
    names.INERTIA_SETPOINT: ("setpoint_stamp", "setpoint", "answering from the last good setpoint"),
    names.IMU: ("imu", "imu", "keeping the last good"),
    names.INERTIA: ("inertia", "inertia", "keeping the last good"),
}


class IkTetherAllocatorNode(Node):
    """Answers inertia setpoints with rate-limited, taut-tether joint commands."""

    def __init__(self, **kwargs) -> None:
        super().__init__(NODE_NAME, **default_sim_time(kwargs))
        try:
            values = declare_parameters(self, PARAMETERS, on_live_change=self._apply_live)
            self.core = AllocatorTick(
                RobotModel(),
                *self._configs(values),
                health=config_from_values(HEALTH_CONFIG, values),
                clock_ns=lambda: sim_clock_ns(self),
                publishers=self.count_publishers,
            )
        except ValueError as exc:  # the core names the parameter it refuses
            self.destroy_node()
            if isinstance(exc, InvalidParameterError):
                raise
            raise InvalidParameterError(f"parameter {exc}") from exc
        self._commands_pub = self.create_publisher(
            JointState, names.JOINT_COMMANDS, qos_for(names.JOINT_COMMANDS)
        )
        self._diagnostics_pub = self.create_publisher(
            DiagnosticArray, names.DIAGNOSTICS, qos_for(names.DIAGNOSTICS)
        )
        self._health_pub = self.create_publisher(
            DiagnosticArray, names.JOINT_HEALTH, qos_for(names.JOINT_HEALTH)
        )
        for msg_type, topic, callback in (
            (Vector3Stamped, names.INERTIA_SETPOINT, self._on_setpoint),
            (Imu, names.IMU, self._on_imu),
            (Vector3Stamped, names.INERTIA, self._on_inertia),
            (JointState, names.JOINT_STATES, self._on_joint_states),
        ):
            self.create_subscription(msg_type, topic, callback, qos_for(topic))
        config, model = self.core.config, self.core.model
        self.get_logger().info(
            f"ik_tether_allocator ready: tick {config.control_period_s * 1e3:g} ms, "
            f"tension margin {config.tension_margin_n:g} N, joint speed "
            f"{model.joint_speed_max_rad_s * config.speed_fraction:.1f} rad/s, reel "
            f"{model.tether_speed_max_m_s * config.speed_fraction:.2f} m/s"
        )

    @property
    def config(self) -> AllocatorConfig:
        """The allocator's settings in force (live changes included)."""
        return self.core.config

    @staticmethod
    def _configs(
        values: Mapping[str, ParameterValue],
    ) -> tuple[AllocatorConfig, AllocatorTickSettings, CommandLeadConfig]:
        return tuple(config_from_values(config, values) for config in CONFIGS)  # type: ignore[return-value]

    def _apply_live(self, values: Mapping[str, ParameterValue]) -> None:
        """A live parameter change, applied from the next tick on."""
        self.core.configure(*self._configs(values))

    # --- callbacks: message -> core call -> messages -------------------------------------
    def _on_setpoint(self, msg: Vector3Stamped) -> None:
        def use(t_ns: int) -> TickOutput:
            sample = vector3_from_msg(msg)
            return self.core.setpoint(t_ns, sample.vector, sample.frame_id)

        self._take(names.INERTIA_SETPOINT, msg, use)

    def _on_imu(self, msg: Imu) -> None:
        def use(t_ns: int) -> TickOutput:
            sample = imu_from_msg(msg)
            return self.core.imu(
                t_ns,
                sample.angular_velocity_rad_s,
                msg.header.frame_id,
                specific_force_m_s2=sample.linear_acceleration_m_s2,
            )

        self._take(names.IMU, msg, use)

    def _on_inertia(self, msg: Vector3Stamped) -> None:
        def use(t_ns: int) -> TickOutput:
            return self.core.measured_inertia(t_ns, principal_inertia_from_msg(msg).vector)

        self._take(names.INERTIA, msg, use)

    def _on_joint_states(self, msg: JointState) -> None:
        """Measured joints: faults found, then ``/splitter/joint_health`` while there are any.

        A bad stamp (negative, behind the last, far ahead) or content (names, sizes,
        non-finite) is warned and counted; nothing is changed."""
        core = self.core
        t_ns = admitted_stamp(self, core.stamps, names.JOINT_STATES, msg, key="joint_states")
        if t_ns is None:
            core.count_rejected()
            return
        try:
            sample = joint_state_from_msg(msg)
        except MessageValidationError as exc:
            core.count_rejected()
            warn_throttled(
                self, "joint_states", f"rejected {names.JOINT_STATES}: {exc}; nothing changed"
            )
            return
        for detection in core.joint_states(t_ns, sample.position):
            self.get_logger().error(
                f"t = {detection.t_ns * 1e-9:.3f} s: joint {detection.joint_name} is faulty "
                f"({detection.symptom}): re-planning without it"
            )
        if core.remaining is None:
            return
        health = joint_health_status(
            core.health.symptoms, core.remaining.reachable(core.model), NODE_NAME
        )
        self._health_pub.publish(diagnostics_to_msg(t_ns, [health]))

    def _take(self, topic: str, msg, use: Callable[[int], TickOutput]) -> None:
        """Admit the stamp of ``msg``, hand it to the core (``use``), publish the outcome."""
        stamp_key, key, consequence = INPUTS[topic]
        core = self.core
        t_ns = admitted_stamp(
            self, core.stamps, topic, msg, key=stamp_key, not_before_ns=core.not_before_ns(topic)
        )
        if t_ns is None:
            core.count_rejected()
            return
        try:
            out = use(t_ns)
        except MessageValidationError as exc:  # the message did not convert
            out = core.rejected(topic, t_ns, str(exc))
        if out.rejected is not None:
            warn_throttled(
                self,
                key,
                f"rejected {topic} at t = {t_ns * 1e-9:.3f} s: {out.rejected}; {consequence}",
            )
        self._publish(out)

    def _publish(self, out: TickOutput) -> None:
        for a in out.commands:
            if a.saturated:
                warn_throttled(
                    self,
                    "projected",
                    f"setpoint {np.round(a.requested_inertia_kg_m2, 4).tolist()} kg m^2 at "
                    f"t = {a.t_ns * 1e-9:.3f} s is unreachable: projected onto the reachable set",
                )
            try:
                command = joint_state_to_msg(a.t_ns, a.joint_position, a.joint_velocity)
            except MessageValidationError as exc:
                self.get_logger().error(f"command not published: {exc}", throttle_duration_sec=2.0)
                return
            self._commands_pub.publish(command)
        if out.refused is not None:
            self.get_logger().error(out.refused, throttle_duration_sec=2.0)
        if out.closed_window is not None and out.answered_ns is not None:
            status = self._status(self.core.status(out.closed_window, self._extra_values()))
            try:
                msg = diagnostics_to_msg(out.answered_ns, [status])
            except MessageValidationError as exc:
                self.get_logger().error(
                    f"diagnostics not published: {exc}", throttle_duration_sec=2.0
                )
            else:
                self._diagnostics_pub.publish(msg)

    # --- diagnostics ---------------------------------------------------------------------
    def _extra_values(self) -> dict[str, int | str]:
        """The node's warning counts and live parameter changes."""
        values: dict[str, int | str] = {
            f"total_warnings_{key}": count for key, count in sorted(rejection_counts(self).items())
        }
        values.update(parameter_diagnostics(self))
        return values

    @staticmethod
    def _status(status: AllocatorStatus) -> DiagnosticStatusSample:
        return DiagnosticStatusSample(
            name=STATUS_NAME, level=status.level, message=status.message, values=status.values
        )

    def diagnostics_status(self) -> DiagnosticStatusSample:
        """The status of the current window (also what the next /diagnostics carries)."""
        return self._status(self.core.status(extra=self._extra_values()))


def main(args: list[str] | None = None) -> int:
    """Spin until Ctrl-C or shutdown; an invalid parameter exits with 1 naming it."""
    return run_node(lambda stop: IkTetherAllocatorNode(), NODE_NAME, args)


if __name__ == "__main__":
    raise SystemExit(main())
