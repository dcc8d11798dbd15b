"""Live parameters on the whole graph (issue 28, item 3; DESIGN.md section 5).

Every node the project starts (the scenario's graph with its recorder, the
player, the Foxglove bridge and the graph watchdog) is built in one process with
the parameters the launcher gives it. For every parameter of every node a
runtime set of a wrong type, and for numbers a NaN and an out-of-range value,
for strings an unknown choice, for arrays a wrong length and a NaN, is refused
with a reason and leaves the value unchanged; a start-up parameter is refused as
read-only even with a valid value. rclpy's own parameters: ``use_sim_time``
(rclpy refuses a wrong type itself; a bool would switch the node's clock live,
which the launcher chose: refused by the project's callback) and
``start_type_description_service`` (read-only in rclpy).

A valid live change of an MPC weight changes the next solve (same input, cold
start both times); live changes of the allocator and gait manager reach their
core objects and the ``/diagnostics`` they publish. A few sets go through the
``~/set_parameters`` service, as ``ros2 param set`` and rqt_reconfigure send them.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.serialization import serialize_message

from splitter_bag import BagWriter, QosProfile
from splitter_bag.player_node import PlayerNode
from splitter_bringup.nodes.foxglove_bridge_node import FoxgloveBridgeNode
from splitter_bringup.nodes.graph_watchdog_node import GraphWatchdogNode
from splitter_bringup.run.inprocess import create_node
from splitter_bringup.scenario.definition import load_scenario
from splitter_bringup.scenario.graph_config import graph_nodes
from splitter_model.model import PAPER_INITIAL_RADII_M, RobotModel, principal_inertia
from splitter_msgs_py import conversions as cv
from splitter_msgs_py.parameters import parameter_diagnostics

TEST_DOMAIN_ID = int(os.environ["ROS_DOMAIN_ID"])  # set by the root conftest.py
NAN = float("nan")
RCLPY_PARAMETERS = {"use_sim_time", "start_type_description_service"}
# What a user tunes during a flight (README, "Live parameters") is live, at least.
EXPECTED_LIVE = {
    "inertial_morphing_mpc": {
        "enabled",
        "q_w",
        "r",
        "q_t",
        "q_q",
        "q_tq",
        "tension_slack_weight",
        "objective",
        "recovery_spin_rad_s",
        "recovery_momentum_ratio_max",
        "fault_effort_scale",
        "diagnostics_period_s",
    },
    "ik_tether_allocator": {
        "tension_margin_n",
        "low_spin_tension_fraction",
        "reference_velocity_window_s",
        "diagnostics_period_s",
    },
    "gait_phase_manager": {
        "stance_force_threshold_n",
        "touchdown_debounce_s",
        "liftoff_debounce_s",
        "landed_speed_m_s",
        "landed_angular_speed_rad_s",
        "landed_dwell_s",
        "jump_settle_speed_m_s",
        "jump_settle_angular_speed_rad_s",
    },
}
W0 = np.array([-0.3, -0.9, 0.9])  # [rad/s] Table I's initial rate
Q0 = np.array([1.0, 0.0, 0.0, 0.0])
I0 = principal_inertia(RobotModel(), PAPER_INITIAL_RADII_M)


def _tiny_bag(folder: Path) -> Path:
    bag_dir = folder / "player_bag"
    with BagWriter(bag_dir) as writer:
        writer.add_topic("/test/a", "geometry_msgs/msg/Vector3Stamped", [QosProfile(depth=10)])
        for t in range(0, 100_000_000, 10_000_000):
            writer.write("/test/a", serialize_message(cv.vector3_to_msg(t, [0.0, 0.0, 0.0])), t, t)
    return bag_dir


@pytest.fixture(scope="module")
def nodes(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Node]]:
    """Every node kind of the project, built as the launcher builds it, in one context."""
    folder = tmp_path_factory.mktemp("live_parameters")
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=TEST_DOMAIN_ID)
    built: dict[str, Node] = {}
    try:
        scenario = load_scenario("lunar_jumping")  # has a jump plan: every gait parameter set
        for launch in graph_nodes(scenario, bag_dir=folder / "bag"):
            built[launch.name] = create_node(launch, context)
        built["player"] = PlayerNode(
            context=context,
            parameter_overrides=[
                Parameter("bag", value=str(_tiny_bag(folder))),
                Parameter("start_delay_s", value=60.0),  # does not play during the test
            ],
        )
        built["foxglove_bridge"] = FoxgloveBridgeNode(
            context=context, parameter_overrides=[Parameter("port", value=0)]
        )
        built["graph_watchdog"] = GraphWatchdogNode(context=context)
        yield built
    finally:
        for name, node in built.items():
            if name == "player":
                node.stop()
            node.destroy_node()
        context.try_shutdown()


def _wrong_values(node: Node, name: str) -> list[tuple[str, object]]:
    """(what, value) pairs no parameter of this type and descriptor may take."""
    param = node.get_parameter(name)
    kind = param.type_
    descriptor = node.describe_parameter(name)
    cases: list[tuple[str, object]] = []
    if kind in (Parameter.Type.DOUBLE, Parameter.Type.INTEGER):
        cases += [("wrong type", "not a number"), ("wrong type", [1.0, 2.0]), ("NaN", NAN)]
        ranges = descriptor.floating_point_range or descriptor.integer_range
        if ranges:
            lo, hi = ranges[0].from_value, ranges[0].to_value
            if math.isfinite(hi):
                cases.append(("out of range", float(hi) + 1.0 + abs(hi)))
            if math.isfinite(lo):
                cases.append(("out of range", float(lo) - 1.0 - abs(lo)))
        else:
            cases.append(("out of range", -1.0e300))  # every project number is bounded
        if kind == Parameter.Type.INTEGER:
            cases.append(("wrong type", 1.5))
    elif kind == Parameter.Type.STRING:
        cases += [("wrong type", 3.0), ("wrong type", [1.0]), ("unknown choice", "no_such_choice")]
    elif kind == Parameter.Type.BOOL:
        cases += [("wrong type", "yes"), ("wrong type", 1.0), ("NaN", NAN)]
    elif kind == Parameter.Type.DOUBLE_ARRAY:
        value = list(param.value)
        cases += [
            ("wrong type", "1, 2, 3"),
            ("wrong type", ["a"] * max(1, len(value))),
            ("wrong length", [*value, 0.0]),
            ("NaN", [NAN] * max(1, len(value))),
        ]
    else:  # string arrays, and lists declared empty (rclpy stores no item type for them)
        cases += [("wrong type", 3.0), ("wrong type", [NAN]), ("NaN", NAN)]
    return cases


def _same(a: object, b: object) -> bool:
    return repr(a) == repr(b)  # equal values, NaN included; arrays item by item


def _live(node: Node, name: str) -> bool:
    return name not in RCLPY_PARAMETERS and not node.describe_parameter(name).read_only


def test_every_parameter_is_read_only_or_live_as_documented(nodes) -> None:
    for node_name, node in nodes.items():
        live = {
            n for n in node.list_parameters([], 0).names if _live(node, n) and n != "use_sim_time"
        }
        # the ones a user tunes in flight are live (a node may add more, validated alike)
        assert EXPECTED_LIVE.get(node_name, set()) <= live, node_name
        for name in live:
            assert "[live" in node.describe_parameter(name).description
        for name in set(node.list_parameters([], 0).names) - live - RCLPY_PARAMETERS:
            assert "read-only" in node.describe_parameter(name).description, (node_name, name)


def test_every_invalid_runtime_set_is_refused_with_a_reason(nodes) -> None:
    refused = 0
    parameters = 0
    for node_name, node in nodes.items():
        for name in node.list_parameters([], 0).names:
            parameters += 1
            before = node.get_parameter(name).value
            type_before = node.describe_parameter(name).type
            read_only = node.describe_parameter(name).read_only
            for what, value in _wrong_values(node, name):
                result = node.set_parameters([Parameter(name, value=value)])[0]
                where = f"{node_name}.{name} = {value!r} ({what})"
                assert not result.successful, where
                assert result.reason.strip(), where
                if read_only:
                    assert "read-only" in result.reason, (where, result.reason)
                elif name not in RCLPY_PARAMETERS:  # the project's validation names it
                    assert name in result.reason, (where, result.reason)
                assert _same(node.get_parameter(name).value, before), where
                assert node.describe_parameter(name).type == type_before, where
                refused += 1
        assert parameter_diagnostics(node).get("parameter_changes", 0) == 0, node_name
    print(
        f"{refused} invalid runtime sets refused over {parameters} parameters of {len(nodes)} nodes"
    )
    assert parameters > 100 and refused >= 3 * parameters


def test_a_start_up_parameter_is_refused_as_read_only_even_when_valid(nodes) -> None:
    checked = 0
    for node_name, node in nodes.items():
        for name in node.list_parameters([], 0).names:
            if _live(node, name):
                continue
            current = node.get_parameter(name)
            if current.type_ == Parameter.Type.NOT_SET:
                continue  # an empty list from a parameter file: nothing valid to send back
            result = node.set_parameters([current])[0]
            assert not result.successful, (node_name, name)
            if name == "use_sim_time":
                assert "read at start-up" in result.reason
            else:
                assert result.reason == f"Trying to set a read-only parameter: {name}."
            checked += 1
    assert checked > 100


def test_a_live_mpc_weight_changes_the_next_solve(nodes) -> None:
    node = nodes["inertial_morphing_mpc"]
    controller = node.controller
    controller.set_reference(0, [0.0, 1.0, 0.0], Q0)

    def solve() -> tuple[np.ndarray, float]:
        controller.mpc.reset()  # cold start: the same input gives the same solve
        controller.on_state(0, W0, Q0, I0, None)
        assert controller.status.solve_ok, controller.status.solve_status
        return controller.plan.inertia.copy(), controller.status.cost

    before, cost_before = solve()
    again, cost_again = solve()
    np.testing.assert_array_equal(again, before)
    assert cost_again == cost_before
    result = node.set_parameters([Parameter("q_w", value=[100.0, 1.0, 100.0])])[0]
    assert result.successful, result.reason
    assert controller.weights.q_w == (100.0, 1.0, 100.0)
    after, cost_after = solve()
    change = float(np.max(np.abs(after - before)))
    print(
        f"q_w 100,100,100 -> 100,1,100: plan inertia moved {change:.4f} kg m^2, cost "
        f"{cost_before:.4f} -> {cost_after:.4f}"
    )
    assert change > 1e-3
    assert cost_after != cost_before
    assert parameter_diagnostics(node) == {
        "parameter_changes": 1,
        "last_parameter_change": "q_w = [100.0, 1.0, 100.0]",
    }
    # q_q > 0 needs the attitude in the solver's state: lunar_jumping's MPC is built without it
    assert not controller.config.mpc.attitude_states
    result = node.set_parameters([Parameter("q_q", value=10.0)])[0]
    assert not result.successful and "restart" in result.reason
    assert node.get_parameter("q_q").value == 0.0
    assert controller.weights.q_q == 0.0
    node.set_parameters([Parameter("q_w", value=[100.0, 100.0, 100.0])])
    np.testing.assert_array_equal(solve()[0], before)


def test_live_changes_reach_the_allocator_and_the_gait_manager(nodes) -> None:
    allocator = nodes["ik_tether_allocator"]
    assert allocator.set_parameters([Parameter("tension_margin_n", value=2)])[0].successful
    assert allocator.config.tension_margin_n == 2.0
    status = allocator.diagnostics_status().values  # what its next /diagnostics carries
    assert status["tension_margin_setting_n"] == 2.0
    assert status["parameter_changes"] == 1
    assert status["last_parameter_change"] == "tension_margin_n = 2.0"
    gait = nodes["gait_phase_manager"]
    result = gait.set_parameters([Parameter("touchdown_debounce_s", value=0.05)])[0]
    assert result.successful, result.reason
    assert gait.config.touchdown_debounce_ns == 50_000_000
    assert len(gait.config.jumps) == 2  # the plan is kept
    assert parameter_diagnostics(gait)["parameter_changes"] == 1


def test_the_set_parameters_service_refuses_and_applies(nodes) -> None:
    context = nodes["simulator"].context
    user = rclpy.create_node("parameter_user", context=context)
    executor = SingleThreadedExecutor(context=context)
    for node in (user, nodes["ik_tether_allocator"], nodes["simulator"]):
        executor.add_node(node)
    try:

        def call(target: str, name: str, value) -> object:
            client = AsyncParameterClient(user, target)
            assert client.wait_for_services(timeout_sec=10.0)
            future = client.set_parameters([Parameter(name, value=value)])
            deadline = time.monotonic() + 10.0
            while not future.done():
                assert time.monotonic() < deadline, "no answer from ~/set_parameters"
                executor.spin_once(timeout_sec=0.05)
            return future.result().results[0]

        result = call("ik_tether_allocator", "tension_margin_n", NAN)
        assert not result.successful and "tension_margin_n" in result.reason
        result = call("ik_tether_allocator", "tension_margin_n", 3.0)
        assert result.successful
        assert nodes["ik_tether_allocator"].config.tension_margin_n == 3.0
        result = call("simulator", "dt_s", 0.001)
        assert not result.successful and "read-only" in result.reason
        result = call("simulator", "gravity", "jupiter")
        assert not result.successful and "read-only" in result.reason
    finally:
        executor.remove_node(nodes["ik_tether_allocator"])
        executor.remove_node(nodes["simulator"])
        user.destroy_node()
