"""``gait_phase_manager``: sequences Launch, In-Flight, Jump, Landing and Landed.

ROS plumbing over :class:`splitter_mpc.core.gait_tick.GaitTick` (inputs, their
checks, the tick joining, the answer; the library loop drives the same object)
and its :class:`~splitter_mpc.core.gait.GaitPhaseMachine`.

Lockstep (docs/ARCHITECTURE.md, item 5): the node answers control tick ``t``
(``t`` on the ``control_period_s`` grid) once it holds ``/splitter/imu``, both
rangefinders, both leg load cells and ``/splitter/joint_states`` stamped ``t`` (and
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
  limits of :mod:`splitter_mpc.core.gait_tick`, inertia outside (0, 1e4] kg m^2)
  still answers its tick, from the last good message of that topic, so lockstep
  never stalls on bad data; with several publishers on the topic it answers
  nothing (it may be a stranger's: the tick waits for the real input).

Subscribes only to what the robot measures: ``/splitter/imu`` (attitude, gyro,
accelerometer), ``/splitter/hemi_{a,b}/range`` (height), ``/splitter/hemi_{a,b}/leg_force``
(stance: the legs push harder than ``stance_force_threshold_n``),
``/splitter/joint_states`` (``r_x`` = tether joint / 2), and ``/splitter/inertia``
in mode ``momentum_aligned`` only (the principal moments the controllers use: with
the gyro's rate, the angular momentum that mode aligns the reference with; remapped
to the flight estimator's with robot errors). Never the odometry or the contact
wrenches (ground truth).
Publishes: ``/splitter/jump_command`` (every tick), ``/splitter/gait_phase``,
``/splitter/attitude_reference`` and ``/splitter/attitude_reference_pose``
(latched, on change), ``/diagnostics`` (every ``diagnostics_period_s`` of
simulated time). Parameters: the fields of :class:`~splitter_mpc.core.gait.GaitConfig`
and :class:`~splitter_mpc.core.gait_tick.GaitNodeSettings`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, TwistStamped, Vector3Stamped, WrenchStamped
from rclpy.node import Node
from sensor_msgs.msg import Imu, JointState, Range
from std_msgs.msg import Bool, String

from splitter_model.actuators import TETHER_INDEX
from splitter_mpc.core.gait import GaitConfig, GaitOutput
from splitter_mpc.core.gait_sensing import BodySensingConfig, ImuReading
from splitter_mpc.core.gait_tick import (
    GaitAnswer,
    GaitNodeSettings,
    GaitTick,
    gait_settings_from_parameters,
)
from splitter_mpc.core.tick_inputs import TickEvents
from splitter_msgs_py import names
from splitter_msgs_py.conversions import (
    MessageValidationError,
    imu_from_msg,
    joint_state_from_msg,
    pose_to_msg,
    principal_inertia_from_msg,
    range_from_msg,
    twist_to_msg,
    wrench_from_msg,
    wrench_to_msg,
)
from splitter_msgs_py.core.stamps import refusal_answers_tick
from splitter_msgs_py.node_pattern import admitted_stamp, run_node, sim_clock_ns
from splitter_msgs_py.node_status import publish_status
from splitter_msgs_py.parameters import (
    InvalidParameterError,
    ParameterValue,
    declare_parameters,
    specs_from_config,
    warn_throttled,
)
from splitter_msgs_py.qos import LATCHED_QOS, qos_for

NODE_NAME = "gait_phase_manager"
PARAMETERS = (
    *specs_from_config(GaitNodeSettings),
    *specs_from_config(GaitConfig),
    *specs_from_config(BodySensingConfig),
)
ZERO = (0.0, 0.0, 0.0)


def _frame(field_name: str, got: str, expected: str) -> None:
    if got != expected:
        raise MessageValidationError(f"{field_name}: expected '{expected}', got {got!r}")


def _read_imu(msg: Imu) -> ImuReading:
    _frame("header.frame_id", msg.header.frame_id, names.BASE_FRAME)
    sample = imu_from_msg(msg)
    return ImuReading(
        sample.orientation_wxyz, sample.angular_velocity_rad_s, sample.linear_acceleration_m_s2
    )


def _range_reader(frame: str) -> Callable[[Range], float]:
    def read(msg: Range) -> float:
        _frame("header.frame_id", msg.header.frame_id, frame)
        return range_from_msg(msg)[1]

    return read


def _read_leg_force(msg: WrenchStamped) -> object:
    sample = wrench_from_msg(msg)
    _frame("header.frame_id", sample.frame_id, names.BASE_FRAME)
    return sample.force_n


def _read_tether(msg: JointState) -> float:
    return float(joint_state_from_msg(msg).position[TETHER_INDEX])


READERS: dict[str, tuple[type, Callable[[object], object]]] = {
    names.IMU: (Imu, _read_imu),
    names.RANGE_A: (Range, _range_reader(names.HEMI_FRAMES[0])),
    names.RANGE_B: (Range, _range_reader(names.HEMI_FRAMES[1])),
    names.LEG_FORCE_A: (WrenchStamped, _read_leg_force),
    names.LEG_FORCE_B: (WrenchStamped, _read_leg_force),
    names.JOINT_STATES: (JointState, _read_tether),
    names.INERTIA: (Vector3Stamped, lambda msg: principal_inertia_from_msg(msg).vector),
}


def _named_parameter_error(exc: ValueError) -> InvalidParameterError:
    """``InvalidParameterError`` from a core ``ValueError`` whose text starts with the name."""
    name, _, reason = str(exc).partition(": ")
    return InvalidParameterError(f"parameter '{name}': {reason}")


class GaitPhaseManagerNode(Node):
    """Answers every control tick with a jump command; publishes phase and references."""

    def __init__(self, **kwargs) -> None:
        super().__init__(NODE_NAME, **kwargs)
        try:
            values = declare_parameters(self, PARAMETERS, on_live_change=self._apply_live)
            try:
                config, settings, sensing = gait_settings_from_parameters(values)
            except ValueError as exc:
                raise _named_parameter_error(exc) from exc
        except InvalidParameterError:
            self.destroy_node()
            raise
        self.tick = GaitTick(config, settings, sensing)
        self._jump_pub = self.create_publisher(
            WrenchStamped, names.JUMP_COMMAND, qos_for(names.JUMP_COMMAND)
        )
        self._phase_pub = self.create_publisher(String, names.GAIT_PHASE, LATCHED_QOS)
        self._stance_pub = self.create_publisher(Bool, names.STANCE_SHAPE, LATCHED_QOS)
        self._w_ref_pub = self.create_publisher(TwistStamped, names.ATTITUDE_REFERENCE, LATCHED_QOS)
        self._q_ref_pub = self.create_publisher(
            PoseStamped, names.ATTITUDE_REFERENCE_POSE, LATCHED_QOS
        )
        self._diagnostics_pub = self.create_publisher(
            DiagnosticArray, names.DIAGNOSTICS, qos_for(names.DIAGNOSTICS)
        )
        for topic in self.tick.ticks.inputs:
            self.create_subscription(
                READERS[topic][0],
                topic,
                lambda msg, topic=topic: self._on_input(topic, msg),
                qos_for(topic),
            )
        self.get_logger().info(
            f"{len(config.jumps)} jump(s) planned at "
            f"{[j.time_ns / 1e9 for j in config.jumps]} s; attitude reference "
            f"'{config.attitude_reference}', w_ref {list(config.w_ref_rad_s)} rad/s"
        )

    @property
    def config(self) -> GaitConfig:
        """The validated configuration of the gait phase machine."""
        return self.tick.config

    def _apply_live(self, values: Mapping[str, ParameterValue]) -> None:
        """A live change of the contact and landing thresholds, from the next tick on."""
        try:
            config, _, _ = gait_settings_from_parameters(values)
        except ValueError as exc:
            raise _named_parameter_error(exc) from exc
        self.tick.machine.config = config

    # -- inputs --------------------------------------------------------------------------
    def _on_input(self, topic: str, msg: object) -> None:
        """Stamp rules, then the message read and checked (None: rejected), filed."""
        t_ns = admitted_stamp(
            self, self.tick.stamps, topic, msg, consequence="dropped, keeping the last good message"
        )
        if t_ns is None:
            return
        try:
            value = self.tick.checked(topic, READERS[topic][1](msg))
        except MessageValidationError as exc:
            if not refusal_answers_tick(self.count_publishers(topic)):
                warn_throttled(
                    self,
                    topic,
                    f"rejected {topic} stamped {t_ns * 1e-9:.3f} s: {exc}; not taken as the "
                    "tick's input (several publishers)",
                )
                return
            warn_throttled(
                self, topic, f"rejected {topic} stamped {t_ns * 1e-9:.3f} s: {exc}; using last good"
            )
            value = None
        events, answer = self.tick.add(topic, t_ns, value, lambda: sim_clock_ns(self))
        self._log_events(events)
        if answer is not None:
            self._publish(answer)

    def _log_events(self, events: TickEvents) -> None:
        for tick, had in events.dropped:
            self.get_logger().warning(
                f"tick {tick * 1e-9:.3f} s dropped: inputs never completed (had {list(had)})"
            )
        if events.completed is not None:
            t_done = events.completed[0]
            for tick, had in events.skipped:
                self.get_logger().warning(
                    f"tick {tick * 1e-9:.3f} s skipped: tick {t_done * 1e-9:.3f} s completed "
                    f"first (had {list(had)})"
                )

    # -- the answer ----------------------------------------------------------------------
    def _publish(self, answer: GaitAnswer) -> None:
        t_ns, output = answer.t_ns, answer.output
        if answer.no_good_input:
            warn_throttled(
                self, "no_good_input", f"tick {t_ns * 1e-9:.3f} s: no good input yet; zero thrust"
            )
        if answer.error:
            self.get_logger().error(
                f"tick {t_ns * 1e-9:.3f} s: gait update failed: {answer.error}",
                throttle_duration_sec=2.0,
            )
        try:
            if output is None:
                jump = wrench_to_msg(t_ns, ZERO, ZERO, names.WORLD_FRAME)
            else:
                jump = wrench_to_msg(
                    t_ns, output.jump_force_n, output.jump_torque_nm, names.WORLD_FRAME
                )
        except MessageValidationError as exc:
            self.get_logger().error(f"tick {t_ns * 1e-9:.3f} s: jump command refused ({exc}); zero")
            jump = wrench_to_msg(t_ns, ZERO, ZERO, names.WORLD_FRAME)
        if output is not None:  # the tick's phase and reference go out before its answer
            if output.phase_changed:
                self.get_logger().info(
                    f"gait phase {output.phase.value} at t = {t_ns * 1e-9:.3f} s: {output.reason}"
                )
                self._phase_pub.publish(String(data=output.phase.value))
            if answer.stance_shape_changed:
                self._stance_pub.publish(Bool(data=output.stance_shape))
            if output.reference is not None:
                self._publish_reference(output)
        self._jump_pub.publish(jump)
        if answer.diagnostics is not None:
            publish_status(
                self, self._diagnostics_pub, t_ns, f"{NODE_NAME}: gait phase", answer.diagnostics
            )

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


def main(args: list[str] | None = None) -> int:
    """Run the node until Ctrl-C or shutdown; an invalid parameter stops it with exit code 1."""
    return run_node(lambda stop: GaitPhaseManagerNode(), NODE_NAME, args)


if __name__ == "__main__":
    raise SystemExit(main())
