"""Garbage of every kind on every input topic of the launched graph (issue 13).

The node processes run as ``splitter launch`` starts them (lockstep); this test's
process publishes garbage on every topic a node subscribes to for 10 s of wall time
(:mod:`splitter_tools.garbage`) and checks everything the nodes publish meanwhile.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from splitter_bringup.scenario.definition import load_scenario
from splitter_model.faults import JointFault
from splitter_msgs_py import names
from splitter_msgs_py.conversions import joint_health_from_msg
from splitter_msgs_py.core.stamps import MessageValidationError
from splitter_msgs_py.inspection import non_finite_fields
from splitter_tools.garbage import garbage_message, run_with_garbage


def test_garbage_messages_are_garbage() -> None:
    rng = np.random.default_rng(1)
    bad = [
        garbage_message(names.INERTIA_SETPOINT, "value", 0, rng) for _ in range(50)
    ]  # NaN, inf or |x| >= 1e300 in one field of each
    assert all(
        non_finite_fields(m) or max(abs(m.vector.x), abs(m.vector.y), abs(m.vector.z)) >= 1e300
        for m in bad
    )
    ahead = garbage_message(names.JOINT_COMMANDS, "stamp_ahead", 10_000_000, rng)
    assert ahead.header.stamp.sec >= 3600
    for _ in range(50):  # the MPC refuses every health report, the simulator every fault
        with pytest.raises(MessageValidationError):
            joint_health_from_msg(garbage_message(names.JOINT_HEALTH, "value", 0, rng))
        fault = garbage_message(names.FAULT_INJECTION, "value", 0, rng)
        with pytest.raises(ValueError):
            JointFault(fault.key, fault.value, 0.0)


@pytest.mark.slow
def test_garbage_on_every_input_topic_kills_no_node_and_the_flight_converges(tmp_path) -> None:
    suite_domain = os.environ["ROS_DOMAIN_ID"]
    report = run_with_garbage(
        load_scenario("spin_stabilization"),
        tmp_path,
        garbage_s=10.0,
        domain_id=int(suite_domain) + 14,
    )
    # the process's domain is given back (later tests rely on it)
    assert os.environ["ROS_DOMAIN_ID"] == suite_domain
    assert report.launch.outcome == "ended" and report.deaths == [], report.launch
    assert report.garbage_s >= 9.0 and report.garbage_sent > 2000
    assert report.non_finite == ()
    for topic in (names.IMU, names.INERTIA_SETPOINT, names.JOINT_COMMANDS, names.JUMP_COMMAND):
        assert report.outputs.get(topic, 0) > 500, report.outputs
    # no healthy joint was taken for faulty (the allocator reports health only after
    # a detection): garbage answered no lockstep tick, so no command came late
    assert report.outputs.get(names.JOINT_HEALTH, 0) == 0, report.outputs
    w = report.final_w_rad_s  # the paper's stabilization still happens
    assert abs(w[0]) < 0.01 and abs(w[2]) < 0.01 and abs(w[1]) / np.linalg.norm(w) > 0.99, w
