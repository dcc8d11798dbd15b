"""QoS profiles of the graph: one explicit ``QoSProfile`` per kind of traffic."""

from __future__ import annotations

from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
)

from splitter_msgs_py import names


def _reliable(depth: int, durability: DurabilityPolicy = DurabilityPolicy.VOLATILE) -> QoSProfile:
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=durability,
    )


# State and command streams: reliable so that lockstep never loses a tick, and deep
# enough that a recorder keeps up at the graph's full rate.
STATE_QOS = _reliable(depth=100)
COMMAND_QOS = STATE_QOS
# /clock as ROS publishes it for simulated time.
CLOCK_QOS = _reliable(depth=100)
# Latched: late joiners get the current gait phase and reference (DESIGN.md section 4).
LATCHED_QOS = _reliable(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
# Visualisation and diagnostics.
DIAGNOSTICS_QOS = _reliable(depth=50)
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
    names.STANCE_SHAPE: LATCHED_QOS,
    names.ATTITUDE_REFERENCE: LATCHED_QOS,
    names.ATTITUDE_REFERENCE_POSE: LATCHED_QOS,
    names.JUMP_COMMAND: COMMAND_QOS,
    names.CONTACT_WRENCH_A: STATE_QOS,
    names.CONTACT_WRENCH_B: STATE_QOS,
    names.RANGE_A: STATE_QOS,
    names.RANGE_B: STATE_QOS,
    names.LEG_FORCE_A: STATE_QOS,
    names.LEG_FORCE_B: STATE_QOS,
    names.TRUTH_IMU: STATE_QOS,
    names.TRUTH_INERTIA: STATE_QOS,
    names.FAULT_INJECTION: COMMAND_QOS,
    names.TRUTH_JOINT_FAULTS: LATCHED_QOS,
    names.JOINT_HEALTH: LATCHED_QOS,
    names.MARKERS: MARKERS_QOS,
    names.DIAGNOSTICS: DIAGNOSTICS_QOS,
}


def qos_for(topic: str) -> QoSProfile:
    """The project's QoS for ``topic``; unknown topics get ``STATE_QOS``."""
    return TOPIC_QOS.get(topic, STATE_QOS)
