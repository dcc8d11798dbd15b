"""A joint broken at runtime in a running ``splitter launch`` (issue 31): found, handled, recorded.

The graph runs as the user starts it (every node its own process, lockstep). When the
simulated clock passes 1 s, this test publishes on ``/splitter/fault_injection`` what
``ros2 topic pub --once /splitter/fault_injection diagnostic_msgs/msg/KeyValue
"{key: tether, value: locked}"`` sends. The simulator locks the reel; the allocator
finds it from the joint states, the MPC plans within what remains, and the bag holds
the fault (``/splitter/truth/joint_faults``) and its detection
(``/splitter/joint_health``); the flight still converges.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, KeyValue
from rclpy.executors import SingleThreadedExecutor
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from splitter_bag import read_messages
from splitter_bringup.analysis.campaign import classify_flight
from splitter_bringup.run.run_bag import read_run_series
from splitter_msgs_py import conversions as cv
from splitter_msgs_py import names
from splitter_msgs_py.environment import ros_environment
from splitter_msgs_py.qos import qos_for

SPLITTER = Path(sys.executable).with_name("splitter")
INJECT_AT_S = 1.0  # [s] simulated
MAX_INJECTION_LAG_S = 3.0  # [s] simulated: the lockstep graph outruns the injector's spin
DETECTION_WITHIN_S = 0.2  # [s] the bound, from the first commanded motion
STUCK_ERROR_M = 1e-3  # [m] the detector's stuck threshold for the reel (JointHealthConfig)


def first_commanded_motion(bag: Path, locked_at_s: float) -> float | None:
    """First command stamp after ``locked_at_s`` that asks the reel to leave where it
    locked by more than the detector's threshold (None when it is never asked)."""
    locked_length = None
    for record in read_messages(bag, topics=[names.JOINT_STATES, names.JOINT_COMMANDS]):
        msg = deserialize_message(record.data, JointState)
        t = cv.stamp_from_msg(msg.header.stamp) * 1e-9
        if t < locked_at_s:
            continue
        value = msg.position[list(msg.name).index(names.TETHER_JOINT)]
        if record.topic == names.JOINT_STATES:
            locked_length = value if locked_length is None else locked_length
        elif locked_length is not None and abs(value - locked_length) > STUCK_ERROR_M:
            return t
    return None


@pytest.mark.slow
def test_a_reel_locked_at_runtime_is_found_and_the_flight_converges(tmp_path: Path) -> None:
    domain = int(os.environ["ROS_DOMAIN_ID"]) + 17
    env = ros_environment(domain_id=domain)
    launch = subprocess.Popen(
        [str(SPLITTER), "launch", "spin_stabilization", "--variant", "mpc", "--out", str(tmp_path)],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain)
    injected: list[int] = []
    try:
        node = rclpy.create_node("fault_injector", context=context)
        publisher = node.create_publisher(
            KeyValue, names.FAULT_INJECTION, qos_for(names.FAULT_INJECTION)
        )

        def on_clock(msg: Clock) -> None:
            t_ns = cv.stamp_from_msg(msg.clock)
            if not injected and t_ns >= INJECT_AT_S * 1e9:
                publisher.publish(KeyValue(key=names.TETHER_JOINT, value="locked"))
                injected.append(t_ns)

        node.create_subscription(Clock, names.CLOCK, on_clock, qos_for(names.CLOCK))
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        deadline = time.monotonic() + 600.0
        while launch.poll() is None and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        executor.shutdown()
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
        if launch.poll() is None:
            launch.kill()
    assert launch.returncode == 0
    assert injected, "the clock never passed the injection time"
    bag = tmp_path / "bag"
    faults, health = [], []
    for record in read_messages(bag, topics=[names.TRUTH_JOINT_FAULTS, names.JOINT_HEALTH]):
        msg = deserialize_message(record.data, DiagnosticArray)
        sample = cv.diagnostics_from_msg(msg)[0]
        t = cv.stamp_from_msg(msg.header.stamp) * 1e-9
        (faults if record.topic == names.TRUTH_JOINT_FAULTS else health).append((t, sample))
    locked = [t for t, s in faults if s.values.get(names.TETHER_JOINT) == "locked"]
    # the lockstep simulator runs ahead of this injector's clock: the fault lands when the
    # simulator takes the message, after the request
    assert locked and INJECT_AT_S <= locked[0] < INJECT_AT_S + MAX_INJECTION_LAG_S
    found = [t for t, s in health if names.TETHER_JOINT in s.values]
    asked = first_commanded_motion(bag, locked[0])
    assert found and asked is not None
    assert locked[0] < found[0] and found[0] - asked <= DETECTION_WITHIN_S
    series = read_run_series(bag)
    tether = names.JOINT_INDEX[names.TETHER_JOINT]
    marks = series.extras  # what the flight figure marks, from the bag
    assert marks["joint_fault"][-1, tether] == 1 and marks["joint_detected"][-1, tether] == 1
    assert series.t_s[np.argmax(marks["joint_detected"][:, tether] > 0)] == pytest.approx(found[0])
    outcome = classify_flight(series.t_s, series.angular_velocity_rad_s)
    assert outcome.success, outcome
    length = series.joint_position[:, tether]
    after = series.t_s > locked[0] + 0.01
    assert np.ptp(length[after]) == 0.0  # locked where it was


@pytest.mark.slow
def test_a_scheduled_limp_knee_flies_the_same_through_the_graph_and_the_library(
    tmp_path: Path,
) -> None:
    """The simulator's limp joint, the allocator's detection and re-plan and the MPC's
    bounds in the graph's lockstep order: every summary metric as in the library loop."""
    from dataclasses import replace

    from splitter_bringup.analysis.summary import metric_values
    from splitter_bringup.run.graph_run import run_graph_scenario
    from splitter_bringup.run.library import run_closed_loop
    from splitter_bringup.scenario.definition import load_scenario
    from splitter_model.faults import JointFault
    from splitter_tools.bench_graph import largest_relative_difference

    scenario = replace(
        load_scenario("spin_stabilization_reel_locked", "mpc"),
        faults=(JointFault("hemi_a_y_pos_knee", "limp", 0.5),),
        duration_s=3.0,
    )
    graph = run_graph_scenario(scenario, tmp_path)
    library = run_closed_loop(scenario)
    assert graph.extras["joint_detected"][-1, names.JOINT_INDEX["hemi_a_y_pos_knee"]] == 1
    worst, metric = largest_relative_difference(
        metric_values(graph, scenario), metric_values(library, scenario)
    )
    assert worst < 1e-9, f"{metric} differs by {worst:.3g} between graph and library"
