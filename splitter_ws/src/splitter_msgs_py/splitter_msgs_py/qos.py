"""QoS profiles of the graph: one explicit ``QoSProfile`` per kind of traffic."""

from __future__ import annotations

from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
)

from splitter_msgs_py import names

# State and command streams: reliable so that lockstep never loses a tick, and deep
# enough that a recorder keeps up at the graph's full rate.
STATE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
COMMAND_QOS = STATE_QOS
# /clock as ROS publishes it for simulated time.
CLOCK_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
# Latched: late joiners get the current gait phase and reference (DESIGN.md section 4).
LATCHED_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
# Visualisation and diagnostics.
DIAGNOSTICS_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=50,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
MARKERS_QOS = DIAGNOSTICS_QOS

TOPIC_QOS: dict[str, QoSProfile] = {
    names.CLOCK: CLOCK_QOS,
    names.IMU: STATE_QOS,
    names.ODOM: STATE_QOS,
    names.INERTIA: STATE_QOS,
    names.JOINT_STATES: STATE_QOS,
    names.INERTIA_SETPOINT: COMMAND_QOS,
    names.JOINT_COMMANDS: COMMAND_QOS,
    names.GAIT_PHASE: LATCHED_QOS,
    names.ATTITUDE_REFERENCE: LATCHED_QOS,
    names.ATTITUDE_REFERENCE_POSE: LATCHED_QOS,
    names.JUMP_COMMAND: COMMAND_QOS,
    names.CONTACT_WRENCH_A: STATE_QOS,
    names.CONTACT_WRENCH_B: STATE_QOS,
    names.MARKERS: MARKERS_QOS,
    names.DIAGNOSTICS: DIAGNOSTICS_QOS,
}


def qos_for(topic: str) -> QoSProfile:
    """The project's QoS for ``topic``; unknown topics get ``STATE_QOS``."""
    return TOPIC_QOS.get(topic, STATE_QOS)
