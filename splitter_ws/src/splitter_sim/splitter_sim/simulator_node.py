"""``simulator``: the SPLITTER physics as a ROS 2 node, and the clock of the graph.

ROS plumbing over :class:`splitter_sim.core.tick.SimulatorTick` (the simulator, command
queue, stamp rules, lockstep wait, accounting; docs/ARCHITECTURE.md, "Lockstep
protocol"). It publishes ``/clock`` (it does not use sim time) and, stamped ``t`` each
step, joint states, inertia, odometry, contact wrenches, the ground truth
(``/splitter/truth/inertia``, ``/splitter/truth/imu``) and the IMU (its rate gyro's
reading: the true rate with the robot's gyro bias and noise); on the markers grid
the scene (:class:`splitter_sim.core.scene.Scene`) as ``/splitter/scene/masses`` and
``/splitter/markers`` drawn from it; ``/diagnostics``. Faults
(``splitter_model.faults``): ``/splitter/fault_injection`` (KeyValue: a joint's name,
locked or limp) breaks that joint at the simulated time it arrives, as the parameters
``fault_joints``, ``fault_kinds``, ``fault_times_s`` do at their times; the faults it
has are published on ``/splitter/truth/joint_faults`` when they change (latched).
``lockstep``: a steady timer and the command callbacks step it, never blocking;
``real_time``: a wall-clock timer at ``dt_s / rate_factor``. Bad input is warned
(throttled) and counted, never raised. Parameters: the fields of ``SimConfig``,
``SimulatorSettings`` and ``RobotErrors`` (the simulated robot's mass, gyro and
actuator-lag errors).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

from diagnostic_msgs.msg import KeyValue
from geometry_msgs.msg import WrenchStamped
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.task import Future
from sensor_msgs.msg import JointState

from splitter_model.faults import FAULT_NAMES
from splitter_model.model import gravity_from_name
from splitter_msgs_py import conversions as cv
from splitter_msgs_py import names
from splitter_msgs_py.core.stamps import refusal_answers_tick
from splitter_msgs_py.node_pattern import admitted_stamp, run_node
from splitter_msgs_py.parameters import (
    READ_ONLY_NOTE,
    InvalidParameterError,
    config_from_values,
    declare_parameters,
    rejection_counts,
    specs_from_config,
    warn_throttled,
)
from splitter_msgs_py.presence import PublisherPresence
from splitter_msgs_py.qos import qos_for
from splitter_msgs_py.signals import spin_until_stopped
from splitter_sim.core.robot_errors import RobotErrors
from splitter_sim.core.settings import SimulatorSettings
from splitter_sim.core.simulator import SimConfig
from splitter_sim.core.tick import JOINT_KEY, JUMP_KEY, LOCKSTEP_TOPICS, SimulatorTick, StartGate
from splitter_sim.messages import masses_to_msg, scene_markers, state_messages

NODE_NAME = "simulator"
# what the robot's sensors read, every step: the controllers' inputs, waited for at the start
STATE_TOPICS = (
    names.JOINT_STATES,
    names.INERTIA,
    *names.RANGES,
    *names.LEG_FORCES,
    names.IMU,
)
# the ground truth, every step too, but not waited for at the start (no controller reads
# it), except by the subscribers named in startup_wait_for_subscribers (a recorder)
TRUTH_TOPICS = (*names.TRUTH_TOPICS, names.ODOM, *names.CONTACT_WRENCHES)
PUBLISHED = (
    names.CLOCK,
    names.TRUTH_JOINT_FAULTS,
    *STATE_TOPICS,
    *TRUTH_TOPICS,
    names.SCENE_MASSES,
    names.MARKERS,
    names.DIAGNOSTICS,
)
LOCKSTEP_POLL_S = 0.005  # [s] wall period of the lockstep driver timer
SLACK_WARNING_PERIOD_S = 1.0  # [s] wall: at most one tether-slack warning per period
BATCH_WALL_S = 0.02  # [s] longest a free-running callback steps before yielding


class SimulatorNode(Node):
    """Steps the simulator in lockstep with the controllers or in real time."""

    def __init__(self, **kwargs) -> None:
        super().__init__(NODE_NAME, **kwargs)
        try:
            settings, config = self._declared_settings()
            self.tick = SimulatorTick(settings.simulator(config), settings)
        except ValueError as exc:
            self.destroy_node()
            raise InvalidParameterError(str(exc)) from exc
        self.finished = Future()
        self._started = False
        self._first_answer_since: float | None = None  # [s] real time: waiting for tick 0
        self._start_wall = now = time.monotonic()
        self._start = StartGate(settings.startup_wait_s, settings.startup_settle_s, now)
        self._run_wall_start: float | None = None
        self._run_start_unix_s = 0.0  # [s] wall clock (epoch) of the first step
        self._published_t_ns: int | None = None
        self._published_faults: tuple[int, ...] = ()  # fault codes last published
        self._slack_warned_at = -math.inf  # [s] wall time of the last slack warning
        self._has_publisher = PublisherPresence(self)
        self._pubs = {
            topic: self.create_publisher(cv.TOPIC_MESSAGE_CLASSES[topic], topic, qos_for(topic))
            for topic in PUBLISHED
        }
        for msg_type, topic, callback in (
            (JointState, names.JOINT_COMMANDS, self._on_joint_commands),
            (WrenchStamped, names.JUMP_COMMAND, self._on_jump_command),
            (KeyValue, names.FAULT_INJECTION, self._on_fault_injection),
        ):
            self.create_subscription(msg_type, topic, callback, qos_for(topic))
        dt_s, real_time = self.tick.sim.config.dt_s, self.tick.real_time
        period = max(dt_s / settings.rate_factor, 0.001) if real_time else LOCKSTEP_POLL_S  # [s]
        driver = self._on_real_time_timer if real_time else self._advance
        steady = Clock(clock_type=ClockType.STEADY_TIME)  # real time: catch-up does the rest
        self._timer = self.create_timer(period, driver, clock=steady)
        self.tick.pacer.restart(time.monotonic(), self.tick.time_ns)
        self.get_logger().info(f"simulator ready: {self.tick.describe()}")

    @property
    def time_ns(self) -> int:
        """Simulated time of the last step [ns]."""
        return self.tick.time_ns

    def _declared_settings(self) -> tuple[SimulatorSettings, SimConfig]:
        own = declare_parameters(self, specs_from_config(SimulatorSettings))
        values = declare_parameters(self, specs_from_config(SimConfig))
        errors = config_from_values(
            RobotErrors, declare_parameters(self, specs_from_config(RobotErrors))
        )
        settings = config_from_values(SimulatorSettings, own, robot_errors=errors)
        return settings, config_from_values(SimConfig, values, gravity_m_s2=self._gravity())

    def _gravity(self) -> float:
        """``gravity``: a preset name (zero, moon, mars, earth) or a number [m/s^2]."""
        text = "gravity: zero, moon, mars, earth, or a value in m/s^2 (string or number)"
        descriptor = ParameterDescriptor(
            name="gravity", description=text + READ_ONLY_NOTE, dynamic_typing=True, read_only=True
        )
        try:
            value = self.declare_parameter("gravity", "zero", descriptor).value
            if isinstance(value, bool) or not isinstance(value, str | int | float):
                raise ValueError(f"expected a name or a number, got {value!r}")
            return gravity_from_name(value)
        except (ParameterException, ValueError) as exc:
            raise InvalidParameterError(f"parameter 'gravity': {exc}") from exc

    def _on_joint_commands(self, msg: JointState) -> None:
        def apply(stamp: int) -> None:
            sample = cv.joint_state_from_msg(msg)
            self.tick.command_joints(stamp, sample.position, sample.velocity)

        self._on_command(names.JOINT_COMMANDS, JOINT_KEY, msg, apply)

    def _on_jump_command(self, msg: WrenchStamped) -> None:
        def apply(stamp: int) -> None:
            sample = cv.wrench_from_msg(msg)
            self.tick.command_jump(stamp, sample.force_n, sample.torque_nm, sample.frame_id)

        self._on_command(names.JUMP_COMMAND, JUMP_KEY, msg, apply)

    def _on_fault_injection(self, msg: KeyValue) -> None:
        """Break a joint now; an unknown joint or kind, or a second fault, is warned."""
        try:
            fault = self.tick.sim.inject_fault(msg.key, msg.value)
        except ValueError as exc:
            warn_throttled(self, "fault_injection", f"rejected {names.FAULT_INJECTION}: {exc}")
            return
        self.get_logger().warning(
            f"t = {fault.time_s:.3f} s: joint {fault.joint} made {fault.kind} "
            f"({names.FAULT_INJECTION})"
        )

    def _publish_faults(self, t_ns: int) -> None:
        """The simulator's faults (ground truth), when they changed."""
        codes = tuple(int(c) for c in self.tick.sim.fault_codes)
        if codes == self._published_faults:
            return
        self._published_faults = codes
        values = {names.JOINT_NAMES[j]: FAULT_NAMES[c] for j, c in enumerate(codes) if c != 0}
        status = cv.DiagnosticStatusSample(
            name=f"{NODE_NAME}: joint faults",
            level=2 if values else 0,
            message=", ".join(f"{j} {k}" for j, k in values.items()) or "no fault",
            values=values,
        )
        self._pubs[names.TRUTH_JOINT_FAULTS].publish(cv.diagnostics_to_msg(t_ns, [status]))

    def _on_command(self, topic: str, key: str, msg, apply: Callable[[int], None]) -> None:
        """Admit the stamp, read and apply the command; either refusal is warned, counted."""
        stamp = admitted_stamp(
            self,
            self.tick.stamps,
            topic,
            msg,
            key=key,
            clock_ns=self.tick.time_ns,
            not_before_ns=self.tick.not_before_ns(topic),
            consequence="dropped, the last good command stays in force",
        )
        if stamp is None:
            return
        try:
            apply(stamp)
        except ValueError as exc:  # MessageValidationError is a ValueError
            answers = refusal_answers_tick(self.count_publishers(topic))
            warn_throttled(
                self,
                key,
                f"rejected {topic} at {stamp * 1e-9:.3f} s: {exc}"
                + ("" if answers else "; not taken as the tick's answer (several publishers)"),
            )
            if answers:
                self.tick.lockstep.arrived(topic, stamp)
        if self._started and self.tick.answers_now(stamp):
            self._advance()

    def _ready_to_start(self) -> bool:
        """Stepping starts once the graph is connected (or ``startup_wait_s`` ran out)."""
        s = self.tick.settings
        lockstep = () if self.tick.real_time else LOCKSTEP_TOPICS
        present = set(self.get_node_names())
        subscribers = {t: self.get_subscriptions_info_by_topic(t) for t in STATE_TOPICS}
        recorded = {
            t: self.get_subscriptions_info_by_topic(t) for t in (*STATE_TOPICS, *TRUTH_TOPICS)
        }
        unpublished = [
            t for t in (*lockstep, *s.startup_wait_for_publishers) if self.count_publishers(t) == 0
        ]
        # The graph cache learns of a subscription before DDS has matched it with our
        # writer: also wait until every state publisher has matched every subscriber.
        missing = (
            [f"a publisher on {t}" for t in unpublished]
            + [f"a subscriber on {t}" for t, infos in subscribers.items() if not infos]
            + [f"node {n}" for n in s.startup_wait_for_nodes if n not in present]
            + [
                f"subscriber {n} on {t}"
                for t, infos in recorded.items()
                for n in s.startup_wait_for_subscribers
                if n not in {i.node_name for i in infos}
            ]
            + [
                f"every DDS match on {p.topic_name}"
                for p in self.publishers
                if p.topic_name in (*STATE_TOPICS, *TRUTH_TOPICS, names.CLOCK)
                and p.get_subscription_count() < self.count_subscribers(p.topic_name)
            ]
        )
        now = time.monotonic()
        if not self._start.may_start(now, missing):
            return False
        if missing:
            self.get_logger().warning(
                f"starting after {now - self._start_wall:.1f} s without {', '.join(missing)}: "
                "topics without a publisher are not waited for"
            )
        self._run_wall_start = time.monotonic()
        self._run_start_unix_s = time.time()
        self.get_logger().info(f"t = {self.tick.time_ns * 1e-9:.2f} s: stepping starts")
        return True

    def _advance(self) -> None:
        """Lockstep driver: publish, wait for the tick's commands, step; never blocks."""
        if self.finished.done():
            return
        self._started = self._started or self._ready_to_start()
        if not self._started:
            return
        budget_end = time.monotonic() + BATCH_WALL_S
        while not self.finished.done():
            if self._published_t_ns != self.tick.time_ns:
                self._publish_state()
                if self._end_reached():
                    return
            if self.tick.on_control_tick() and not self._tick_answered():
                return
            self.tick.step()
            if time.monotonic() > budget_end:
                return

    def _tick_answered(self) -> bool:
        waiting = self.tick.waiting_for(self._has_publisher)
        step, waited = self.tick.lockstep.may_step(waiting, time.monotonic())
        if waited is not None:
            self.get_logger().warning(
                f"lockstep: no message stamped t = {self.tick.time_ns * 1e-9:.3f} s on "
                f"{', '.join(waiting)} after {waited:.1f} s (lockstep_timeout_s); stepping on "
                f"the last good commands ({self.tick.lockstep.timeouts} timeouts so far)"
            )
        return step

    def _on_real_time_timer(self) -> None:
        """Real-time driver: as many steps as the wall clock (x rate_factor) asks for."""
        if self.finished.done():
            return
        now = time.monotonic()
        if not self._started:
            self._started = self._ready_to_start()
            if self._started:
                self._first_answer_since = now
                self._publish_state()
            return
        if self._first_answer_since is not None:  # the clock waits for the first answer
            waiting = self.tick.waiting_for(self._has_publisher)
            waited = now - self._first_answer_since
            if not self.tick.clock_starts(waited, waiting):
                return
            if waiting:
                self.get_logger().warning(
                    f"real time: no answer to the first state on {', '.join(waiting)} after "
                    f"{waited:.1f} s; the clock starts without it"
                )
            self._first_answer_since = None
            self.tick.pacer.restart(now, self.tick.time_ns)
            return
        steps, dropped = self.tick.pacer.steps_due(now, self.tick.time_ns)
        for _ in range(steps):
            if self.finished.done():
                return
            self.tick.step()
            self._publish_state()
            self._end_reached()
        if dropped and not self.finished.done():
            behind_s = self.tick.fell_behind(now)
            self.get_logger().warning(
                f"real time: {behind_s:.3f} s behind at rate_factor "
                f"{self.tick.settings.rate_factor:g}; pacing from here (every step is still taken; "
                f"{self.tick.backlog_drops} times behind, {self.tick.behind_s:.3f} s in all)",
                throttle_duration_sec=5.0,
            )

    def _end_reached(self) -> bool:
        if not self.tick.finished():
            return False
        self._timer.cancel()
        t = self.tick.time_ns
        self._publish_diagnostics(final=True)
        self.get_logger().info(
            f"t = {t * 1e-9:.2f} s: simulation finished (duration_s reached) after "
            f"{self._wall_rtf()}; {self.tick.summary(rejection_counts(self))}"
        )
        self.finished.set_result(True)
        return True

    def _publish_state(self) -> None:
        t = self._published_t_ns = self.tick.time_ns
        state = self.tick.publishable_state()
        try:
            if state is None:
                raise cv.MessageValidationError("non-finite simulator state")
            msgs = state_messages(state, self.tick.readings(state))
        except cv.MessageValidationError as exc:
            self.tick.unpublished += state is not None
            self.get_logger().error(
                f"t = {t * 1e-9:.3f} s: state not published: {exc}", throttle_duration_sec=2.0
            )
            return
        for topic, msg in msgs:
            self._pubs[topic].publish(msg)
        self._publish_faults(t)
        out = self.tick.published(state)
        now = time.monotonic()  # throttled here: rclpy's throttle looks up the caller's line
        if out.slack_started and now - self._slack_warned_at >= SLACK_WARNING_PERIOD_S:
            self._slack_warned_at = now
            self.get_logger().warning(
                f"t = {t * 1e-9:.3f} s: tether slack (tension {state.tether_tension_n:.3g} N)"
            )
        if out.scene is not None:
            self._pubs[names.SCENE_MASSES].publish(masses_to_msg(out.scene))
            self._pubs[names.MARKERS].publish(scene_markers(out.scene))
        if out.diagnostics:
            self._publish_diagnostics()
        if out.progress:
            self.get_logger().info(f"t = {t * 1e-9:.2f} s ({self._wall_rtf()})")

    def _wall_rtf(self) -> str:
        """Wall time since stepping started and the real-time factor."""
        wall = time.monotonic() - (self._run_wall_start or self._start_wall)
        return (
            f"{wall:.1f} s wall, real-time factor {self.tick.time_ns * 1e-9 / max(wall, 1e-9):.1f}"
        )

    def _publish_diagnostics(self, final: bool = False) -> None:
        status = self.tick.diagnostics(final, rejection_counts(self))
        if status is None:
            return
        level, message, values = status
        if self._run_wall_start is not None:  # wall times (not deterministic)
            values["run_start_unix_s"] = self._run_start_unix_s
            values["flight_wall_time_s"] = time.monotonic() - self._run_wall_start
        sample = cv.DiagnosticStatusSample(f"{NODE_NAME}: physics", level, message, values)
        try:
            self._pubs[names.DIAGNOSTICS].publish(
                cv.diagnostics_to_msg(self.tick.time_ns, [sample])
            )
        except cv.MessageValidationError as exc:
            self.get_logger().error(f"diagnostics not published: {exc}", throttle_duration_sec=2.0)


def main(args: list[str] | None = None) -> int:
    """Run until duration_s (if set), Ctrl-C or shutdown; an invalid parameter exits with 1."""
    return run_node(
        lambda stop: SimulatorNode(),
        NODE_NAME,
        args,
        spin=lambda node, stop: spin_until_stopped(node, stop, finished=node.finished.done),
    )


if __name__ == "__main__":
    raise SystemExit(main())
