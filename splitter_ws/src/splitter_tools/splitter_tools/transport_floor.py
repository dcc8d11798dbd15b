"""The lockstep graph's transport floor: its message traffic with no computation.

What the lockstep graph costs before any physics or control. Nodes named and
wired as in the graph carry the same per-step traffic through rclpy:

* a simulator that publishes, every step, the seven state topics of DESIGN.md
  (``/clock``, imu, odom, inertia, joint states, two contact wrenches) as
  prebuilt messages with a new stamp, and steps on at a control tick only once
  the tick's joint command arrived;
* the gait manager, the MPC and the allocator, each subscribed to what the real
  node subscribes to (:data:`SUBSCRIPTIONS`), answering each control tick once
  its inputs stamped with it arrived (:data:`TICK_ANSWERS`), in the graph's order
  (gait manager, then MPC, then allocator);
* every node but the simulator on simulated time (``use_sim_time``, so each gets
  ``/clock``), and a recorder subscribed raw to every topic.

The callbacks only read the stamp. Markers (25 Hz) and diagnostics (10 Hz) are
left out. One rclpy context, the project's executor, the project's QoS: the
figure is the wall time of the messages alone, to hold against the graph's
flight and the library loop's (``splitter bench graph``).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass

import rclpy
from geometry_msgs.msg import Vector3Stamped, WrenchStamped
from nav_msgs.msg import Odometry
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState, Range

from splitter_msgs_py import names
from splitter_msgs_py.conversions import TOPIC_MESSAGE_CLASSES, stamp_from_msg, stamp_to_msg
from splitter_msgs_py.executors import make_executor
from splitter_msgs_py.qos import qos_for

_LOG = logging.getLogger(__name__)

# What each node of the graph subscribes to (the recorder: every topic, raw). The gait
# manager also takes the measured inertia when its reference is momentum-aligned
# (orientation_tracking): :func:`graph_subscriptions`.
SUBSCRIPTIONS: dict[str, tuple[str, ...]] = {
    "simulator": (names.JOINT_COMMANDS, names.JUMP_COMMAND, names.FAULT_INJECTION),
    "gait_phase_manager": (
        names.IMU,
        *names.RANGES,
        *names.LEG_FORCES,
        names.JOINT_STATES,
    ),
    "inertial_morphing_mpc": (
        names.IMU,
        names.INERTIA,
        names.ATTITUDE_REFERENCE,
        names.ATTITUDE_REFERENCE_POSE,
        names.GAIT_PHASE,
        names.STANCE_SHAPE,
        names.JUMP_COMMAND,
        names.JOINT_HEALTH,
    ),
    "ik_tether_allocator": (
        names.INERTIA_SETPOINT,
        names.IMU,
        names.INERTIA,
        names.JOINT_STATES,
    ),
}
# Per controller: the topic it answers a control tick on, and the inputs it waits for
# (None: every topic it subscribes to).
TICK_ANSWERS: dict[str, tuple[str, tuple[str, ...] | None]] = {
    "gait_phase_manager": (names.JUMP_COMMAND, None),
    "inertial_morphing_mpc": (
        names.INERTIA_SETPOINT,
        (names.IMU, names.INERTIA, names.JUMP_COMMAND),
    ),
    "ik_tether_allocator": (
        names.JOINT_COMMANDS,
        (names.INERTIA_SETPOINT, names.IMU, names.INERTIA),
    ),
}
STATE_TOPICS = (
    names.CLOCK,
    names.JOINT_STATES,
    names.INERTIA,
    names.ODOM,
    names.CONTACT_WRENCH_A,
    names.CONTACT_WRENCH_B,
    *names.RANGES,
    *names.LEG_FORCES,
    names.IMU,
)
RECORDED_TOPICS = (*STATE_TOPICS, names.INERTIA_SETPOINT, names.JOINT_COMMANDS, names.JUMP_COMMAND)
DISCOVERY_TIMEOUT_S = 30.0  # [s] wall: longest wait for every publisher to match
SETTLE_S = 0.5  # [s] wall: executor turns once matched, before the first step
DRAIN_TURNS = 20  # executor turns after the last step, untimed


@dataclass(frozen=True)
class TransportFloor:
    """Wall and CPU time of the graph's traffic alone over ``steps`` simulator steps."""

    steps: int
    simulated_s: float  # [s]
    wall_s: float  # [s]
    cpu_s: float  # [s] of this process
    published: int  # messages published
    delivered: int  # messages taken by a subscription

    @property
    def real_time_factor(self) -> float:
        """Simulated seconds per wall second."""
        return self.simulated_s / self.wall_s

    @property
    def wall_per_step_us(self) -> float:
        """[us] wall per simulator step."""
        return 1e6 * self.wall_s / self.steps


def graph_subscriptions(gait_takes_inertia: bool = False) -> dict[str, tuple[str, ...]]:
    """:data:`SUBSCRIPTIONS`, with the gait manager's inertia when it takes it."""
    table = dict(SUBSCRIPTIONS)
    if gait_takes_inertia:
        table["gait_phase_manager"] = (*table["gait_phase_manager"], names.INERTIA)
    return table


def _state_messages() -> dict[str, object]:
    """One message per state topic, shaped as the simulator's (25 joints, unit quaternion)."""
    joints = JointState(name=list(names.JOINT_NAMES))
    joints.position = [0.1] * names.N_JOINTS
    joints.velocity = [0.0] * names.N_JOINTS
    odom = Odometry(child_frame_id=names.BASE_FRAME)
    odom.header.frame_id = names.WORLD_FRAME
    odom.pose.pose.orientation.w = 1.0
    imu = Imu()
    imu.header.frame_id = names.BASE_FRAME
    imu.orientation.w = 1.0
    inertia = Vector3Stamped()
    inertia.header.frame_id = names.BASE_FRAME
    return {
        names.CLOCK: Clock(),
        names.JOINT_STATES: joints,
        names.INERTIA: inertia,
        names.ODOM: odom,
        names.CONTACT_WRENCH_A: WrenchStamped(),
        names.CONTACT_WRENCH_B: WrenchStamped(),
        **{topic: Range(range=1.0) for topic in names.RANGES},
        **{topic: WrenchStamped() for topic in names.LEG_FORCES},
        names.IMU: imu,
    }


class _Counter:
    def __init__(self) -> None:
        self.published = 0
        self.delivered = 0


class _NullSimulator:
    """Publishes the state topics every step; at a tick, steps on its joint command."""

    def __init__(self, node: Node, steps: int, dt_ns: int, tick_ns: int, count: _Counter) -> None:
        self.node, self.steps, self.dt_ns, self.tick_ns = node, steps, dt_ns, tick_ns
        self.count = count
        self.t_ns = 0
        self.done = False
        self._messages = _state_messages()
        self._publishers = [
            (node.create_publisher(TOPIC_MESSAGE_CLASSES[t], t, qos_for(t)), self._messages[t])
            for t in STATE_TOPICS
        ]
        node.create_subscription(
            JointState, names.JOINT_COMMANDS, self._on_command, qos_for(names.JOINT_COMMANDS)
        )
        node.create_subscription(
            WrenchStamped, names.JUMP_COMMAND, self._on_other, qos_for(names.JUMP_COMMAND)
        )

    def _publish(self) -> None:
        stamp = stamp_to_msg(self.t_ns)
        for publisher, msg in self._publishers:
            if isinstance(msg, Clock):
                msg.clock = stamp
            else:
                msg.header.stamp = stamp
            publisher.publish(msg)
        self.count.published += len(self._publishers)

    def advance(self) -> None:
        """Publish and step until a tick needs its command (the last one included)."""
        while True:
            self._publish()
            if self.t_ns % self.tick_ns == 0:
                return
            self.t_ns += self.dt_ns

    def _on_command(self, msg: JointState) -> None:
        self.count.delivered += 1
        if self.done or stamp_from_msg(msg.header.stamp) != self.t_ns:
            return
        if self.t_ns >= self.steps * self.dt_ns:
            self.done = True  # the controllers answered the last state
            return
        self.t_ns += self.dt_ns
        self.advance()

    def _on_other(self, _msg: object) -> None:
        self.count.delivered += 1


def _tick_answerer(
    context: Context,
    name: str,
    *,
    subscriptions: tuple[str, ...],
    tick_ns: int,
    count: _Counter,
    overrides: list[Parameter],
) -> Node:
    """A node subscribed as ``name`` is, answering each tick once its inputs arrived."""
    node = Node(name, context=context, parameter_overrides=overrides)
    answer_topic, inputs = TICK_ANSWERS[name]
    inputs = subscriptions if inputs is None else inputs
    answer = TOPIC_MESSAGE_CLASSES[answer_topic]()
    if isinstance(answer, JointState):
        answer.name = list(names.JOINT_NAMES)
        answer.position = [0.1] * names.N_JOINTS
        answer.velocity = [0.0] * names.N_JOINTS
    publisher = node.create_publisher(type(answer), answer_topic, qos_for(answer_topic))
    arrived: dict[int, set[str]] = {}
    needed = set(inputs)

    def on_message(topic: str, msg) -> None:
        count.delivered += 1
        if topic not in needed:
            return
        t_ns = stamp_from_msg(msg.header.stamp)
        if t_ns % tick_ns:
            return
        got = arrived.setdefault(t_ns, set())
        got.add(topic)
        if got >= needed:
            del arrived[t_ns]
            answer.header.stamp = msg.header.stamp
            publisher.publish(answer)
            count.published += 1

    for topic in subscriptions:
        node.create_subscription(
            TOPIC_MESSAGE_CLASSES[topic],
            topic,
            _bind(on_message, topic),
            qos_for(topic),
        )
    return node


def _bind(callback: Callable[[str, object], None], topic: str) -> Callable[[object], None]:
    return lambda msg: callback(topic, msg)


def _recorder(context: Context, count: _Counter, overrides: list[Parameter]) -> Node:
    node = Node("recorder", context=context, parameter_overrides=overrides)

    def on_payload(_data: bytes) -> None:
        count.delivered += 1

    for topic in RECORDED_TOPICS:
        node.create_subscription(
            TOPIC_MESSAGE_CLASSES[topic], topic, on_payload, qos_for(topic), raw=True
        )
    return node


def _expected_subscriptions(topic: str, table: dict[str, tuple[str, ...]]) -> int:
    """Subscriptions on ``topic``: the table's, the recorder's, and every sim-time clock."""
    count = sum(topic in topics for topics in table.values()) + (topic in RECORDED_TOPICS)
    if topic == names.CLOCK:
        count += len(TICK_ANSWERS) + 1  # the controllers' and the recorder's time sources
    return count


def _wait_until_matched(
    executor, nodes: list[Node], table: dict[str, tuple[str, ...]], timeout_s: float
) -> None:
    """Spin until every publisher matched all its subscriptions (reliable QoS delivers
    nothing to a reader not matched yet, and the tick chain would wait forever)."""
    publishers = [
        p for node in nodes for p in node.publishers if p.topic_name in TOPIC_MESSAGE_CLASSES
    ]
    deadline = time.monotonic() + timeout_s
    while True:
        unmatched = [
            p.topic_name
            for p in publishers
            if p.get_subscription_count() < _expected_subscriptions(p.topic_name, table)
        ]
        if not unmatched:
            return
        if time.monotonic() > deadline:
            raise TimeoutError(
                f"transport floor: no full DDS match after {timeout_s:g} s on {unmatched}"
            )
        executor.spin_once(timeout_sec=0.05)


def measure_transport_floor(
    duration_s: float,
    dt_s: float = 0.005,
    control_period_s: float = 0.01,
    *,
    subscriptions: dict[str, tuple[str, ...]] | None = None,
    domain_id: int | None = None,
    timeout_s: float = 600.0,
) -> TransportFloor:
    """Run the traffic of ``duration_s`` simulated seconds (see the module) and time it.

    ``duration_s`` must be a whole number of control periods, and those of steps
    ``dt_s``; ``subscriptions`` defaults to :data:`SUBSCRIPTIONS`. The wall time runs
    from the first state published to the last tick's joint command taken.
    """
    dt_ns = round(dt_s * 1e9)
    tick_ns = round(control_period_s * 1e9)
    end_ns = round(duration_s * 1e9)
    if dt_ns <= 0 or tick_ns % dt_ns or end_ns <= 0 or end_ns % tick_ns:
        raise ValueError(
            f"duration_s ({duration_s}) must be a positive multiple of control_period_s "
            f"({control_period_s}), and that of dt_s ({dt_s})"
        )
    steps = end_ns // dt_ns
    table = SUBSCRIPTIONS if subscriptions is None else subscriptions
    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    nodes: list[Node] = []
    try:
        count = _Counter()
        sim_time = [Parameter("use_sim_time", value=True)]
        sim_node = Node("simulator", context=context)
        nodes.append(sim_node)
        simulator = _NullSimulator(sim_node, steps, dt_ns, tick_ns, count)
        nodes += [
            _tick_answerer(
                context,
                name,
                subscriptions=table[name],
                tick_ns=tick_ns,
                count=count,
                overrides=sim_time,
            )
            for name in TICK_ANSWERS
        ]
        nodes.append(_recorder(context, count, sim_time))
        executor = make_executor(context)
        for node in nodes:
            executor.add_node(node)
        _wait_until_matched(executor, nodes, table, DISCOVERY_TIMEOUT_S)
        settle_end = time.monotonic() + SETTLE_S
        while time.monotonic() < settle_end:
            executor.spin_once(timeout_sec=0.05)
        wall0, cpu0 = time.perf_counter(), time.process_time()
        simulator.advance()
        deadline = time.monotonic() + timeout_s
        while not simulator.done:
            if time.monotonic() > deadline:
                raise TimeoutError(
                    f"transport floor stalled at t = {simulator.t_ns * 1e-9:.3f} s "
                    f"after {timeout_s:g} s wall"
                )
            executor.spin_once(timeout_sec=0.5)
        wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        for _ in range(DRAIN_TURNS):  # the recorder's last messages, for the counts
            executor.spin_once(timeout_sec=0.01)
        _LOG.info("transport floor: %d steps in %.2f s wall", steps, wall)
        return TransportFloor(
            steps=steps,
            simulated_s=steps * dt_ns * 1e-9,
            wall_s=wall,
            cpu_s=cpu,
            published=count.published,
            delivered=count.delivered,
        )
    finally:
        for node in nodes:
            node.destroy_node()
        context.try_shutdown()
