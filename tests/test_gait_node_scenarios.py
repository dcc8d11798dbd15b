"""The launcher's gait phase manager parameters of every scenario start the node."""

from __future__ import annotations

import pytest
import rclpy
from rclpy.parameter import Parameter

from splitter_bringup.scenario.definition import available_scenarios, load_scenario
from splitter_bringup.scenario.graph_config import graph_nodes, write_parameter_file
from splitter_mpc.core.gait import PlannedJump
from splitter_mpc.gait_phase_manager_node import GaitPhaseManagerNode


@pytest.mark.parametrize("scenario_name", available_scenarios())
def test_launcher_parameters_of_every_scenario_start_the_node(
    ros_context, tmp_path, scenario_name: str
) -> None:
    """The launcher's parameters, as overrides (in-process graph) and as a params file.

    Scenarios without jumps give empty lists, which arrive untyped: they mean no jump.
    """
    scenario = load_scenario(scenario_name)
    launch = next(
        n for n in graph_nodes(scenario) if n.node_class.endswith(":GaitPhaseManagerNode")
    )
    expected = tuple(PlannedJump.from_spec(j) for j in scenario.jumps)
    overrides = [Parameter(k, value=v) for k, v in launch.parameters.items()]
    node = GaitPhaseManagerNode(context=ros_context, parameter_overrides=overrides)
    try:
        assert node.config.jumps == expected
        assert node.config.attitude_reference == scenario.controller.attitude_reference
    finally:
        node.destroy_node()
    params_file = write_parameter_file(launch, tmp_path)
    context = rclpy.Context()
    rclpy.init(context=context, args=["--ros-args", "--params-file", str(params_file)])
    try:
        node = GaitPhaseManagerNode(context=context)
        assert node.config.jumps == expected
        assert node.get_parameter("use_sim_time").value is True
        node.destroy_node()
    finally:
        context.try_shutdown()
