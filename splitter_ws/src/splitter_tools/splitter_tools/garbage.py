"""Garbage on every input topic of a running graph, and a watch on what the nodes publish.

:class:`GarbageNode` publishes, at ``rate_hz`` per topic, messages that every node
must reject (:data:`INPUT_TOPICS`, every topic some node subscribes to): NaN and
infinite values, finite magnitudes up to 1e300, wrong array sizes, unknown joint
names, frames and phase strings, stamps zero, backwards or far ahead; joint-health
reports with bounds NaN, missing or crossed, or unknown joints; fault injections
naming no joint or no fault (a valid one would break a joint). Each kind
is drawn from a seeded generator (deterministic). Garbage is published serialized
and its payloads are remembered, so that :class:`OutputWatch`, which receives
every message on those topics, tells the nodes' own outputs from the garbage and
counts the non-finite ones among them.

:func:`run_with_garbage` launches a scenario's graph (lockstep or real time) with
both in this process for ``garbage_s`` of wall time once the simulation runs.
"""

from __future__ import annotations

import logging
import math
import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.serialization import deserialize_message, serialize_message
from rclpy.signals import SignalHandlerOptions

from splitter_bringup.run.launcher import LaunchResult, launch
from splitter_bringup.scenario.definition import Scenario
from splitter_msgs_py import names
from splitter_msgs_py.conversions import (
    TOPIC_MESSAGE_CLASSES,
    joint_health_from_msg,
    stamp_from_msg,
)
from splitter_msgs_py.core.stamps import MessageValidationError
from splitter_msgs_py.environment import apply_ros_environment
from splitter_msgs_py.inspection import non_finite_fields
from splitter_msgs_py.qos import LATCHED_QOS, qos_for

LOG = logging.getLogger(__name__)
# every topic a node of the graph subscribes to
INPUT_TOPICS = (
    names.IMU,
    names.INERTIA,
    names.ODOM,
    names.INERTIA_SETPOINT,
    names.JOINT_COMMANDS,
    names.JUMP_COMMAND,
    names.ATTITUDE_REFERENCE,
    names.ATTITUDE_REFERENCE_POSE,
    names.GAIT_PHASE,
    *names.CONTACT_WRENCHES,
    names.JOINT_STATES,
    names.JOINT_HEALTH,
    names.FAULT_INJECTION,
)
JOINT_STATE_TOPICS = (names.JOINT_COMMANDS, names.JOINT_STATES)
LATCHED_TOPICS = (names.ATTITUDE_REFERENCE, names.ATTITUDE_REFERENCE_POSE, names.GAIT_PHASE)
BAD_NUMBERS = (math.nan, math.inf, -math.inf, 1e300, -1e300, 1.7e308)
BAD_STRINGS = ("", "garbage", "world\x00", "base ", "\u00e9\u00e9", "LANDEDX", "x" * 300)
FAR_AHEAD_NS = 3_600 * 1_000_000_000  # [ns]
INT32_MAX = 2**31 - 1
KINDS = ("value", "stamp_zero", "stamp_behind", "stamp_ahead", "frame", "size")
# A reference is set once (stamped 0) and replaced by a later one: a plausible reference
# stamped at or after the last one is a valid new reference, not garbage.
LATCHED_KINDS = ("value", "stamp_ahead", "frame")


def _float_fields(msg: object, prefix: str = "") -> list[tuple[object, str, str]]:
    """(owner, field, type) of every float and float-sequence field of ``msg``, nested."""
    out = []
    for name, kind in msg.get_fields_and_field_types().items():
        value = getattr(msg, name)
        if kind in ("double", "float"):
            out.append((msg, name, "scalar"))
        elif kind.startswith(("sequence<double", "double[", "float[", "sequence<float")):
            out.append((msg, name, "array"))
        elif hasattr(value, "get_fields_and_field_types"):
            out += _float_fields(value, f"{prefix}{name}.")
    return out


def _set_stamp(msg: object, t_ns: int) -> None:
    msg.header.stamp.sec = int(t_ns // 1_000_000_000)
    msg.header.stamp.nanosec = int(t_ns % 1_000_000_000)


def garbage_message(topic: str, kind: str, now_ns: int, rng: np.random.Generator) -> object:
    """One message on ``topic`` that its subscribers must reject (``kind`` of :data:`KINDS`)."""
    cls = TOPIC_MESSAGE_CLASSES[topic]
    msg = cls()
    if topic == names.GAIT_PHASE:
        msg.data = str(rng.choice(BAD_STRINGS))
        return msg
    if topic == names.FAULT_INJECTION:  # a joint that is none, or a fault that is none
        if rng.random() < 0.5:
            msg.key, msg.value = str(rng.choice(BAD_STRINGS)), "locked"
        else:
            msg.key = str(rng.choice(names.JOINT_NAMES))
            msg.value = str(rng.choice(BAD_STRINGS))
        return msg
    if topic == names.JOINT_HEALTH:
        msg.status = [_garbage_health_status(rng)]
        if rng.random() < 0.1:
            msg.status = [] if rng.random() < 0.5 else [msg.status[0], msg.status[0]]
        msg.header.frame_id = names.BASE_FRAME
        _set_stamp(msg, now_ns)
        if kind == "stamp_zero":
            _set_stamp(msg, 0)
        return msg
    # plausible contents first, then one thing wrong
    for owner, name, shape in _float_fields(msg):
        if shape == "scalar":
            setattr(owner, name, float(rng.uniform(-1.0, 1.0)))
    if topic in JOINT_STATE_TOPICS:
        msg.name = list(names.JOINT_NAMES)
        msg.position = [0.1] * names.N_JOINTS
        msg.velocity = [0.0] * names.N_JOINTS
    frame = names.WORLD_FRAME if topic in (names.ODOM, names.JUMP_COMMAND) else names.BASE_FRAME
    if topic in JOINT_STATE_TOPICS:
        frame = ""  # as the allocator and the simulator send them
    msg.header.frame_id = frame
    _set_stamp(msg, now_ns)
    if kind == "stamp_zero":
        _set_stamp(msg, 0)
    elif kind == "stamp_behind":
        _set_stamp(msg, max(0, now_ns - int(rng.integers(2, 1000)) * 10_000_000))
        if now_ns < 20_000_000:
            _set_stamp(msg, 0)
    elif kind == "stamp_ahead":
        msg.header.stamp.sec = int(
            rng.choice([INT32_MAX, (now_ns + FAR_AHEAD_NS) // 1_000_000_000])
        )
    elif kind == "frame" and topic in JOINT_STATE_TOPICS:  # its strings are the names
        joint_names = list(msg.name)
        joint_names[int(rng.integers(len(joint_names)))] = str(rng.choice(BAD_STRINGS))
        msg.name = joint_names
    elif kind == "frame":
        msg.header.frame_id = str(rng.choice(BAD_STRINGS))
    elif kind == "size":
        if topic in JOINT_STATE_TOPICS:
            size = int(rng.integers(0, 3 * names.N_JOINTS))
            msg.position = [0.0] * size
            msg.name = [str(rng.choice(BAD_STRINGS))] * int(rng.integers(0, 30))
        else:
            kind = "value"
    if kind == "value":
        fields = _float_fields(msg)
        owner, name, shape = fields[int(rng.integers(len(fields)))]
        bad = float(rng.choice(BAD_NUMBERS))
        if shape == "scalar":
            setattr(owner, name, bad)
        else:
            values = list(getattr(owner, name)) or [0.0]
            values[int(rng.integers(len(values)))] = bad
            setattr(owner, name, values)
    return msg


def _garbage_health_status(rng: np.random.Generator) -> DiagnosticStatus:
    """A joint-health status the MPC must refuse: a bound NaN, infinite, missing, not
    positive or not below its maximum, or an unknown joint."""
    values = {"hemi_a_y_pos_knee": "stuck"}
    for axis in "xyz":
        values[f"radius_min_{axis}_m"] = "0.1"
        values[f"radius_max_{axis}_m"] = "0.4"
    axis = str(rng.choice(list("xyz")))
    wrong = int(rng.integers(5))
    if wrong == 0:
        values[f"radius_min_{axis}_m"] = str(rng.choice(["nan", "inf", "-inf", "garbage"]))
    elif wrong == 1:
        values.pop(f"radius_max_{axis}_m")
    elif wrong == 2:
        values[f"radius_min_{axis}_m"] = str(rng.choice(["0.0", "-0.2"]))
    elif wrong == 3:
        values[f"radius_min_{axis}_m"] = "0.5"  # above its maximum
    else:
        values[str(rng.choice(BAD_STRINGS))] = "stuck"
    return DiagnosticStatus(
        level=DiagnosticStatus.ERROR,
        name="garbage: joint health",
        message="garbage",
        values=[KeyValue(key=k, value=v) for k, v in values.items()],
    )


class GarbageNode(Node):
    """Publishes garbage on :data:`INPUT_TOPICS` at ``rate_hz`` each while ``active``."""

    def __init__(self, rate_hz: float, watch: OutputWatch, seed: int = 0, **kwargs) -> None:
        super().__init__("garbage", **kwargs)
        self.rng = np.random.default_rng(seed)
        self.active = True
        self.watch = watch  # its payloads: what was sent; its now_ns: the simulated time
        self.sent = 0
        self._garbage_publishers = {
            topic: self.create_publisher(
                TOPIC_MESSAGE_CLASSES[topic],
                topic,
                LATCHED_QOS if topic in LATCHED_TOPICS else qos_for(topic),
            )
            for topic in INPUT_TOPICS
        }
        self.create_timer(1.0 / rate_hz, self._publish)

    def _publish(self) -> None:
        if not self.active:
            return
        for topic, publisher in self._garbage_publishers.items():
            kind = str(self.rng.choice(LATCHED_KINDS if topic in LATCHED_TOPICS else KINDS))
            payload = serialize_message(garbage_message(topic, kind, self.watch.now_ns, self.rng))
            self.watch.payloads.add(payload)
            publisher.publish(payload)
            self.sent += 1


@dataclass
class OutputWatch:
    """Counts of what the nodes published on the input topics (garbage left out)."""

    outputs: dict[str, int] = field(default_factory=dict)
    non_finite: list[str] = field(default_factory=list)
    payloads: set[bytes] = field(default_factory=set)  # the garbage sent
    now_ns: int = 0  # [ns] the latest simulated time a state carried
    last_w: list[tuple[float, np.ndarray]] = field(default_factory=list)  # (t [s], w [rad/s])


class WatchNode(Node):
    """Receives every message on :data:`INPUT_TOPICS` (raw) and checks the nodes' ones."""

    def __init__(self, watch: OutputWatch, **kwargs) -> None:
        super().__init__("garbage_watch", **kwargs)
        self._watch = watch
        for topic in INPUT_TOPICS:
            self.create_subscription(
                TOPIC_MESSAGE_CLASSES[topic],
                topic,
                lambda data, t=topic: self._on_message(t, bytes(data)),
                LATCHED_QOS if topic in LATCHED_TOPICS else qos_for(topic),
                raw=True,
            )

    def _on_message(self, topic: str, payload: bytes) -> None:
        if payload in self._watch.payloads:
            return
        msg = deserialize_message(payload, TOPIC_MESSAGE_CLASSES[topic])
        self._watch.outputs[topic] = self._watch.outputs.get(topic, 0) + 1
        bad = non_finite_fields(msg)
        if bad:
            self._watch.non_finite.append(f"{topic}: {', '.join(bad)}")
        if topic == names.JOINT_HEALTH:  # its numbers are strings: read as the MPC does
            try:
                joint_health_from_msg(msg)
            except MessageValidationError as exc:
                self._watch.non_finite.append(f"{topic}: {exc}")
        if topic == names.IMU:
            t_ns = stamp_from_msg(msg.header.stamp)
            self._watch.now_ns = max(self._watch.now_ns, t_ns)
            w = msg.angular_velocity
            self._watch.last_w.append((t_ns * 1e-9, np.array([w.x, w.y, w.z])))


@dataclass(frozen=True)
class GarbageReport:
    """How a graph fared under garbage."""

    launch: LaunchResult
    garbage_sent: int
    garbage_s: float  # [s] wall time garbage was published
    outputs: dict[str, int]
    non_finite: tuple[str, ...]
    final_w_rad_s: np.ndarray  # mean body rate over the last second of the run

    @property
    def deaths(self) -> list[str]:
        """Nodes that exited with a non-zero code."""
        return [n for n, code in self.launch.exit_codes.items() if code not in (0, None)]


def run_with_garbage(
    scenario: Scenario,
    out_dir: Path,
    *,
    real_time: bool = False,
    garbage_s: float = 10.0,
    start_after_s: float = 0.5,
    rate_hz: float = 50.0,
    domain_id: int | None = None,
    seed: int = 0,
    on_progress: Callable[[float], None] | None = None,
) -> GarbageReport:
    """Launch ``scenario`` and publish garbage for ``garbage_s`` once ``start_after_s`` flew.

    The process's ``ROS_DOMAIN_ID`` is ``domain_id`` during the run and restored after it.
    """
    previous_domain = os.environ.get("ROS_DOMAIN_ID")
    apply_ros_environment(domain_id=domain_id)
    context = Context()
    rclpy.init(context=context, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
    watch = OutputWatch()
    watcher = WatchNode(watch, context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(watcher)
    window = {"start": math.nan, "end": math.nan}
    stop = threading.Event()
    made: list[GarbageNode] = []

    def spin() -> None:
        # The garbage node (publishers on the nodes' own topics) comes only once the
        # simulation runs: the simulator's start-up waits for those topics' publishers.
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.05)
            now = time.monotonic()
            if not made and watch.now_ns >= start_after_s * 1e9:
                made.append(GarbageNode(rate_hz, watch, seed, context=context))
                executor.add_node(made[0])
                window["start"] = now
            elif made and made[0].active and now - window["start"] >= garbage_s:
                made[0].active, window["end"] = False, now

    thread = threading.Thread(target=spin, name="garbage", daemon=True)
    thread.start()
    try:
        result = launch(
            scenario,
            out_dir,
            real_time=real_time,
            record=True,
            domain_id=domain_id,
            quiet=True,
            on_progress=on_progress,
        )
    finally:
        stop.set()
        thread.join()
        for node in (*made, watcher):
            node.destroy_node()
        rclpy.try_shutdown(context=context)
        if previous_domain is None:
            os.environ.pop("ROS_DOMAIN_ID", None)
        else:
            os.environ["ROS_DOMAIN_ID"] = previous_domain
    end = window["end"] if not math.isnan(window["end"]) else time.monotonic()
    last = [w for t, w in watch.last_w if t >= watch.last_w[-1][0] - 1.0] if watch.last_w else []
    return GarbageReport(
        launch=result,
        garbage_sent=made[0].sent if made else 0,
        garbage_s=0.0 if math.isnan(window["start"]) else end - window["start"],
        outputs=dict(watch.outputs),
        non_finite=tuple(watch.non_finite),
        final_w_rad_s=np.mean(last, axis=0) if last else np.full(3, np.nan),
    )
