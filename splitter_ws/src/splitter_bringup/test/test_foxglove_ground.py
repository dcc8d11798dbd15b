"""The Foxglove bridge draws the terrain: ``/splitter/ground`` (``foxglove.SceneUpdate``).

* :func:`ground_scene_update`: one entity per ground box (``ground_base_plane``,
  ``ground_step_<i>``), the same ids whatever the robot's position; its cubes carry the
  boxes' poses (checked in the protobuf encoding: a non-zero double field is its
  8 bytes).
* The node: the terrain comes from ``ground_slope_deg``, ``ground_slope_azimuth_deg``
  and ``ground_steps_m`` (declared read-only with the simulator's descriptions and
  ranges); level ground opens no ground channel; a malformed step list is an invalid
  parameter.
* The launcher hands the scenario's ground parameters to the bridge.
"""

from __future__ import annotations

import dataclasses
import struct

import pytest
from rclpy.parameter import Parameter

from splitter_bringup.nodes.foxglove_bridge_node import (
    FoxgloveBridgeNode,
    ground_of_parameters,
    ground_scene_update,
)
from splitter_bringup.run.launcher import FOXGLOVE_BRIDGE, _with_foxglove
from splitter_bringup.scenario.definition import load_scenario
from splitter_bringup.scenario.graph_config import graph_nodes
from splitter_model.terrain import Step, Terrain
from splitter_msgs_py.parameters import InvalidParameterError
from splitter_sim.core.scene import Ground, ground_boxes

STEPS_FLAT = [2.0, 4.0, -1.0, 1.0, 0.3, -3.0, -1.0, 0.5, 2.5, 0.5]  # two steps [m]
PARAMETERS = {
    "ground_slope_deg": 12.0,
    "ground_slope_azimuth_deg": -40.0,
    "ground_steps_m": STEPS_FLAT,
}


def _double(value: float) -> bytes:
    return struct.pack("<d", float(value))


def test_the_update_has_an_entity_per_box_with_its_pose() -> None:
    ground = ground_of_parameters(PARAMETERS)
    assert ground.terrain == Terrain.from_parameters(12.0, -40.0, STEPS_FLAT)
    boxes = ground_boxes(ground, (0.7, -0.3))
    data = ground_scene_update(boxes, 1_500_000_000).encode()
    for name in (b"ground_base_plane", b"ground_step_0", b"ground_step_1"):
        assert name in data
    assert b"ground_step_2" not in data
    for box in boxes:
        values = (*box.centre_m, *box.size_m, *box.orientation_wxyz)
        for value in values:  # proto3 leaves zeros out
            assert value == 0.0 or _double(value) in data
        assert sum(v != 0.0 for v in values) >= 7
    # step 0's cube: centred at its mid-height above the base plane
    step = ground.terrain.steps[0]
    centre_z = ground.terrain.base_height_m(3.0, 0.0) + 0.5 * step.height_m
    assert _double(centre_z) in data
    # the robot elsewhere: the same entities (the plane moved, the steps did not)
    moved = ground_scene_update(ground_boxes(ground, (9.0, 4.0)), 2_000_000_000).encode()
    for name in (b"ground_base_plane", b"ground_step_0", b"ground_step_1"):
        assert name in moved
    assert _double(boxes[1].centre_m[2]) in moved
    assert _double(boxes[0].centre_m[0]) not in moved


def test_level_ground_has_no_entity_and_bad_steps_are_refused() -> None:
    level = ground_of_parameters(
        {"ground_slope_deg": 0.0, "ground_slope_azimuth_deg": 0.0, "ground_steps_m": []}
    )
    assert level == Ground() and ground_boxes(level, (0.0, 0.0)) == ()
    assert b"ground_" not in ground_scene_update((), 0).encode()
    with pytest.raises(InvalidParameterError, match="ground_steps_m"):
        ground_of_parameters({**PARAMETERS, "ground_steps_m": STEPS_FLAT[:-1]})
    with pytest.raises(InvalidParameterError, match="x_max"):
        ground_of_parameters({**PARAMETERS, "ground_steps_m": [4.0, 2.0, -1.0, 1.0, 0.3]})


def test_the_node_takes_the_terrain_from_its_parameters(ros_context) -> None:
    overrides = [Parameter("port", value=0)]
    overrides += [Parameter(name, value=value) for name, value in PARAMETERS.items()]
    node = FoxgloveBridgeNode(context=ros_context, parameter_overrides=overrides)
    try:
        assert node._ground.terrain == Terrain.from_parameters(12.0, -40.0, STEPS_FLAT)
        assert node._ground_channel is not None
        for name, value in PARAMETERS.items():
            assert node.get_parameter(name).value == pytest.approx(value)
        (described,) = node.describe_parameters(["ground_steps_m"])
        assert described.read_only and "5 values each" in described.description
        (slope,) = node.describe_parameters(["ground_slope_deg"])
        assert slope.floating_point_range[0].to_value == pytest.approx(30.0)
    finally:
        node.destroy_node()
    level = FoxgloveBridgeNode(context=ros_context, parameter_overrides=overrides[:1])
    try:
        assert level._ground == Ground() and level._ground_channel is None
        assert level.get_parameter("ground_steps_m").value == []
    finally:
        level.destroy_node()
    with pytest.raises(InvalidParameterError, match="ground"):
        FoxgloveBridgeNode(
            context=ros_context,
            parameter_overrides=[
                Parameter("port", value=0),
                Parameter("ground_steps_m", value=STEPS_FLAT[:4]),
            ],
        )


def test_the_launcher_gives_the_bridge_the_scenario_ground() -> None:
    base = load_scenario("lunar_jumping")
    terrain = Terrain(8.0, 90.0, (Step(20.0, 22.0, -1.0, 1.0, 0.2),))
    scenario = dataclasses.replace(base, terrain=terrain)
    from splitter_bringup.scenario.graph_config import ground_parameters

    nodes = _with_foxglove(graph_nodes(scenario), "127.0.0.1", 0, ground_parameters(scenario))
    (bridge,) = [n for n in nodes if n.name == FOXGLOVE_BRIDGE]
    assert bridge.parameters["ground_slope_deg"] == 8.0
    assert bridge.parameters["ground_slope_azimuth_deg"] == 90.0
    assert bridge.parameters["ground_steps_m"] == [20.0, 22.0, -1.0, 1.0, 0.2]
    assert bridge.parameters["port"] == 0 and bridge.parameters["use_sim_time"] is True
    simulator = next(n for n in nodes if n.name == "simulator")
    for name in ("ground_slope_deg", "ground_slope_azimuth_deg", "ground_steps_m"):
        assert bridge.parameters[name] == simulator.parameters[name]
